"""The ``boresight`` command: ``main`` (``boresight.cli.main``) and one module per sub-command."""
