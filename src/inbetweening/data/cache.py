"""The prepared-dataset cache: one folder per key holding ``meta.json`` and one ``.npy`` per array.

* The key is a hash of the source files' bytes (memoised against their path, size and mtime) and of every
  preprocessing setting, so a changed file or setting never serves stale data.
* Entries are written into a private temporary folder and renamed into place: readers never see a partial
  entry.  Folders and files get the permissions a plain ``mkdir``/``open`` would give (readable by others).
* ``meta.json`` records a checksum of every array; :func:`load_entry` verifies them all and raises
  :class:`CacheCorrupt` on a mismatch (the caller rebuilds the entry).  The checksum is the wrapping sum and
  the XOR of the array's bytes read as 64-bit words, plus its shape and dtype: it detects changed or truncated
  bytes (a same-size overwrite included) at memory speed, keeping a cached Bandai-Namco-2 load under 0.1 s
  (BENCHMARKS.md); it is an integrity check against corruption, not a cryptographic hash.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from inbetweening.atomic import write_text
from inbetweening.data.sources import find_files

SMALL = ("pos_mean", "pos_std", "offsets")  # loaded into memory; the rest is memory-mapped


class CacheCorrupt(ValueError):
    """A cache entry's bytes do not match the checksums recorded when it was written."""


def default_cache_dir() -> Path:
    return Path(os.environ.get("INBETWEENING_CACHE", Path.home() / ".cache" / "inbetweening"))


def settings_key(settings: dict) -> str:
    return hashlib.sha1(json.dumps(settings, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _stat_signature(path: Path, pattern: str) -> list:
    files = [path] if path.is_file() else find_files(path, pattern)
    return [(str(f), f.stat().st_size, f.stat().st_mtime_ns) for f in files]


def hash_source(path: Path, memo_dir: Path | None = None, pattern: str = "*.bvh") -> str:
    """sha1 over the bytes of a zip file, or over the names and bytes of every file of a folder matching ``pattern``
    (case-insensitively, as the readers match it).

    With ``memo_dir``, the digest is remembered against the files' (path, size, mtime) so an
    unchanged source is not re-read; any change to a file's size or modification time re-hashes it.
    """
    memo = None
    if memo_dir is not None:
        sig = json.dumps(_stat_signature(path, pattern))
        memo = Path(memo_dir) / "hashes" / (hashlib.sha1(sig.encode()).hexdigest() + ".txt")
        if memo.exists():
            digest = memo.read_text().strip()
            if len(digest) == 40 and all(c in "0123456789abcdef" for c in digest):
                return digest
    h = hashlib.sha1()
    if path.is_file():
        with open(path, "rb") as f:
            while chunk := f.read(1 << 22):
                h.update(chunk)
    else:
        for p in find_files(path, pattern):
            h.update(p.name.encode())
            h.update(p.read_bytes())
    digest = h.hexdigest()
    if memo is not None:
        write_text(memo, digest)  # atomic: a reader never sees half a digest
    return digest


def checksum(a: np.ndarray) -> str:
    """``"<dtype>:<shape>:<sum64>:<xor64>"`` of the array's bytes as little-endian 64-bit words (zero-padded)."""
    a = np.ascontiguousarray(a)
    raw = a.reshape(-1).view(np.uint8)
    n = raw.size // 8 * 8
    words = raw[:n].view("<u8")
    tail = np.zeros(8, dtype=np.uint8)
    tail[: raw.size - n] = raw[n:]
    t = tail.view("<u8")
    total = (int(np.add.reduce(words, dtype=np.uint64)) + int(t[0])) % (1 << 64)
    xor = int(np.bitwise_xor.reduce(words)) ^ int(t[0]) if words.size else int(t[0])
    return f"{a.dtype.str}:{'x'.join(map(str, a.shape))}:{total:016x}:{xor:016x}"


def save_entry(path: Path, arrays: dict[str, np.ndarray], meta: dict) -> None:
    """Write a cache entry (arrays + JSON-able ``meta``) atomically; a concurrent writer's entry wins."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=path.name + ".", dir=path.parent))
    try:
        sums = {}
        for k, v in arrays.items():
            v = np.ascontiguousarray(v)
            np.save(tmp / f"{k}.npy", v)
            sums[k] = checksum(v)
        (tmp / "meta.json").write_text(json.dumps({**meta, "checksums": sums}))
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)  # mkdtemp makes 0700: let other users read the shared cache
        for f in tmp.iterdir():
            os.chmod(f, 0o666 & ~umask)
        os.rename(tmp, path)
    except OSError:  # another process wrote the same entry first (or the disk refused): keep theirs
        shutil.rmtree(tmp, ignore_errors=True)


def load_entry(path: Path) -> tuple[dict[str, np.ndarray], dict]:
    """``(arrays, meta)`` of an entry, every array verified against its recorded checksum.

    Raises :class:`CacheCorrupt` (or ``OSError``/``ValueError``/``KeyError`` for unreadable files): rebuild.
    """
    meta = json.loads((path / "meta.json").read_text())
    sums = meta.get("checksums")
    if not isinstance(sums, dict):
        raise CacheCorrupt(f"{path}: no checksums recorded")
    arrays = {}
    for k, want in sums.items():
        a = np.load(path / f"{k}.npy", mmap_mode=None if k in SMALL else "r", allow_pickle=False)
        if checksum(a) != want:
            raise CacheCorrupt(f"{path / (k + '.npy')}: contents do not match the checksum written with it")
        arrays[k] = a
    return arrays, meta
