"""``python -m inbetweening.retarget``: the command line of :mod:`inbetweening.retarget.cli`."""
from inbetweening.retarget.cli import main

if __name__ == "__main__":
    main()
