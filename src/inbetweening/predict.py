"""``python -m inbetweening.predict``: the command-line contract; the tool lives in :mod:`inbetweening.cli.predict`."""
from inbetweening.cli.predict import main

if __name__ == "__main__":
    main()
