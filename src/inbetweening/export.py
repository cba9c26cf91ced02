"""``python -m inbetweening.export``: the command-line contract; the command lives in :mod:`inbetweening.cli.export`."""
from inbetweening.cli.export import main

if __name__ == "__main__":
    main()
