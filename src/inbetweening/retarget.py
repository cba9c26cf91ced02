"""``python -m inbetweening.retarget``: the command-line contract; the tool lives in :mod:`inbetweening.cli.retarget`."""
from inbetweening.cli.retarget import main

if __name__ == "__main__":
    main()
