"""``python -m inbetweening.collect``: the command-line contract; the tool lives in
:mod:`inbetweening.evaluation.collect`."""
import sys

from inbetweening.evaluation.collect import collect, main

__all__ = ["collect", "main"]

if __name__ == "__main__":
    sys.exit(main())
