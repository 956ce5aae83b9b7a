"""``python -m mocapz``: the command line."""

from mocapz.cli.main import main

main()
