"""Finding a dataset's files: a folder (searched recursively), a zip archive (read in place) or one file."""
from __future__ import annotations

import fnmatch
import os
import zipfile
from collections.abc import Iterator
from pathlib import Path

from inbetweening.data.errors import BVHError

__all__ = ["find_files", "iter_bvh_sources"]


def find_files(folder: Path, pattern: str = "*.bvh") -> list[Path]:
    """Files under ``folder`` (recursively) whose name matches ``pattern`` case-insensitively, sorted by path."""
    pat = pattern.lower()
    return sorted(p for p in Path(folder).rglob("*") if fnmatch.fnmatch(p.name.lower(), pat) and p.is_file())


def iter_bvh_sources(path: str | os.PathLike, pattern: str = "*.bvh") -> Iterator[tuple[str, bytes]]:
    """Yield ``(file name without folders, raw bytes)`` for every file matching ``pattern``, sorted by name.

    ``path`` is a folder (searched recursively), a ``.zip`` archive (members are read directly, no
    extraction; ``__MACOSX/`` entries are skipped) or a single file.  ``pattern`` is matched against the
    file name, case-insensitively.  Raises ``FileNotFoundError`` if ``path`` does not exist and
    :class:`BVHError` if it holds no matching file.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"BVH source {str(path)!r} does not exist")
    pat = pattern.lower()
    if path.is_dir():
        files = sorted((p.name, str(p)) for p in find_files(path, pattern))
        if not files:
            raise BVHError(f"no files matching {pattern!r} under this folder", str(path))
        for name, full in files:
            yield name, Path(full).read_bytes()
        return
    if zipfile.is_zipfile(path):
        with zipfile.ZipFile(path) as zf:
            members = sorted(
                (info.filename.rsplit("/", 1)[-1], info.filename, info)
                for info in zf.infolist()
                if not info.is_dir()
                and not info.filename.startswith("__MACOSX/")
                and fnmatch.fnmatch(info.filename.rsplit("/", 1)[-1].lower(), pat)
            )
            if not members:
                raise BVHError(f"no members matching {pattern!r} in this zip file", str(path))
            for name, _, info in members:
                yield name, zf.read(info)
        return
    if fnmatch.fnmatch(path.name.lower(), pat):
        yield path.name, path.read_bytes()
        return
    raise BVHError(f"not a folder, a zip file or a file matching {pattern!r}", str(path))
