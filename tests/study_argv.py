"""The command lines of the studies the tests run, written once.

* ``quiet_study``: a ``montecarlo`` / ``sensitivity`` study as the tests run it — a fixed run count
  (and seed), a given worker count, no figures, no progress output, into a folder;
* ``killable_study``: the study the interruption tests kill part-way — kalman20 with
  ``ground_plane`` in blocks of 100 runs on two workers, long enough to be caught between blocks.

Used by ``tests/project/test_reliability.py``, ``tests/studies/test_study_resume.py`` and
``tests/project/test_public_outputs.py``. Every element is a string (the in-process CLI, a child
process and the reference cases all take it as it is).
"""

from __future__ import annotations

#: the scenario ``killable_study`` runs
KALMAN20 = "scenarios/kiev2012-kalman20.toml"


def quiet_study(command: str, scenario, *options, runs: int, seed: int | None = None, workers: int = 1, out=None) -> list[str]:
    """``COMMAND SCENARIO --runs RUNS [--seed SEED] OPTIONS --workers WORKERS --no-plots --quiet [--out OUT]``."""
    argv = [command, scenario, "--runs", runs]
    if seed is not None:
        argv += ["--seed", seed]
    argv += [*options, "--workers", workers, "--no-plots", "--quiet"]
    if out is not None:
        argv += ["--out", out]
    return [str(a) for a in argv]


def killable_study(command: str, *, runs: int, seed: int | None = None) -> list[str]:
    """``quiet_study`` of kalman20 with ``ground_plane``, blocks (and chunks) of 100 runs, two workers and
    no ``--out`` (the caller adds its folder, and ``--resume``)."""
    blocks = ("--algorithm", "ground_plane", "--block-runs", "100", "--chunk-runs", "100")
    return quiet_study(command, KALMAN20, *blocks, runs=runs, seed=seed, workers=2)
