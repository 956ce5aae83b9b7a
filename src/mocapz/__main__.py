"""``python -m mocapz``: the command line."""

from .cli import main

main()
