"""The estimation core: the measurement model, the noise model and its error structure, the
normal equations, the block-sparse campaign GLS, the Cramér–Rao bound, floated effects, the
algorithm registry, ``estimate`` and the algorithms.

Layer rule (``tests/project/test_layering.py``): modules under ``core/`` import only ``core/``,
``boresight.errors``, ``boresight.stats`` and ``orbits`` — never the data files' formats, the
studies, the reproductions, reporting or the command line.
"""
