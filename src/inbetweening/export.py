"""``python -m inbetweening.export``: the command-line contract; the tool lives in :mod:`inbetweening.tools.export`."""
from inbetweening.tools.export import main

if __name__ == "__main__":
    main()
