"""The data layer's two user-facing errors (the CLI turns both into one line and exit status 2)."""
from __future__ import annotations


class BVHError(ValueError):
    """A malformed BVH file.

    ``str(err)`` is ``"<source>:<line>: <reason>"`` (``"<source>: <reason>"`` when no line applies).
    """

    def __init__(self, reason: str, source: str = "<memory>", line: int | None = None):
        self.reason, self.source, self.line = reason, source, line
        where = f"{source}:{line}" if line is not None else source
        super().__init__(f"{where}: {reason}")

    def __reduce__(self):  # pickled whole (a worker process of the parallel reader raises it in the parent)
        return type(self), (self.reason, self.source, self.line)


class DatasetError(RuntimeError):
    """A dataset could not be found or prepared; the message says which path and what to do."""
