"""``python -m inbetweening.predict``: the command-line contract; the tool lives in :mod:`inbetweening.tools.predict`."""
from inbetweening.tools.predict import main

if __name__ == "__main__":
    main()
