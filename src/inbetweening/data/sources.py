"""Finding a dataset's files: a folder (searched recursively), a zip archive (read in place) or one file."""
from __future__ import annotations

import fnmatch
import os
import zipfile
from collections.abc import Iterator
from pathlib import Path

from inbetweening.data.errors import BVHError

__all__ = ["find_files", "iter_bvh_sources", "list_bvh_sources", "read_bvh_sources"]


def find_files(folder: Path, pattern: str = "*.bvh") -> list[Path]:
    """Files under ``folder`` (recursively) whose name matches ``pattern`` case-insensitively, sorted by path."""
    pat = pattern.lower()
    return sorted(p for p in Path(folder).rglob("*") if fnmatch.fnmatch(p.name.lower(), pat) and p.is_file())


def list_bvh_sources(path: str | os.PathLike, pattern: str = "*.bvh") -> list[tuple[str, str]]:
    """``(file name without folders, key)`` of every file of ``path`` matching ``pattern``, sorted by name; read
    them with :func:`read_bvh_sources`.  ``path`` and the errors are those of :func:`iter_bvh_sources`."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"BVH source {str(path)!r} does not exist")
    pat = pattern.lower()
    if path.is_dir():
        files = sorted((p.name, str(p)) for p in find_files(path, pattern))
        if not files:
            raise BVHError(f"no files matching {pattern!r} under this folder", str(path))
        return files
    if zipfile.is_zipfile(path):
        with zipfile.ZipFile(path) as zf:
            members = sorted(
                (info.filename.rsplit("/", 1)[-1], info.filename)
                for info in zf.infolist()
                if not info.is_dir()
                and not info.filename.startswith("__MACOSX/")
                and fnmatch.fnmatch(info.filename.rsplit("/", 1)[-1].lower(), pat)
            )
        if not members:
            raise BVHError(f"no members matching {pattern!r} in this zip file", str(path))
        return members
    if fnmatch.fnmatch(path.name.lower(), pat):
        return [(path.name, str(path))]
    raise BVHError(f"not a folder, a zip file or a file matching {pattern!r}", str(path))


def read_bvh_sources(path: str | os.PathLike, files: list[tuple[str, str]]) -> Iterator[tuple[str, bytes]]:
    """``(name, raw bytes)`` of the ``files`` :func:`list_bvh_sources` listed for ``path`` (any subset, in order)."""
    path = Path(path)
    if path.is_file() and zipfile.is_zipfile(path):
        with zipfile.ZipFile(path) as zf:
            for name, key in files:
                yield name, zf.read(key)
        return
    for name, key in files:
        yield name, Path(key).read_bytes()


def iter_bvh_sources(path: str | os.PathLike, pattern: str = "*.bvh") -> Iterator[tuple[str, bytes]]:
    """Yield ``(file name without folders, raw bytes)`` for every file matching ``pattern``, sorted by name.

    ``path`` is a folder (searched recursively), a ``.zip`` archive (members are read directly, no
    extraction; ``__MACOSX/`` entries are skipped) or a single file.  ``pattern`` is matched against the
    file name, case-insensitively.  Raises ``FileNotFoundError`` if ``path`` does not exist and
    :class:`BVHError` if it holds no matching file.
    """
    yield from read_bvh_sources(path, list_bvh_sources(path, pattern))
