"""The ``mocapz`` command line, one module per command; :func:`mocapz.cli.main.main` is the entry point."""
