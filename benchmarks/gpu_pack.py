"""Pack Bandai-Namco-2's BVH files for a lent GPU machine (benchmarks/v3_gpu.sh), which takes at most 64 MiB per call
with the working tree: the files alternately into two xz archives (every other one by name), the manifest (name, bytes,
sha1 of every file of both parts) in the second, under ``<out>/p1/part1.tar.xz`` and ``<out>/p2/part2.tar.xz``
(about 38 MiB each); then the two archives, one after the other, cut into pieces of at most ``--piece`` MiB, one per
folder ``<out>/c1``, ``<out>/c2``, ... (one call carries one folder), each with ``pieces.txt`` (the number of pieces,
each archive's name, bytes and sha1), from which the machine puts the archives together again.

    python benchmarks/gpu_pack.py [--zip ../shared/datasets/bandai-namco-2.zip] [--out .gpu] [--part 1 2] [--piece 27]

``--part`` packs only those archives (run ``--part 1`` and ``--part 2`` side by side on two cores, about 5 min, then
``--part`` with no number to cut them); the json files beside the BVH files are not read by the loader and stay behind.
The piece size is what the working tree leaves of a call's 64 MiB (the tree was 35 MiB on 2026-11-28).  ``.gpu/`` must
be git-ignored (``echo /.gpu/ >> .git/info/exclude``).
"""
from __future__ import annotations

import argparse
import hashlib
import io
import lzma
import os
import tarfile
import time
import zipfile

PFX = "Bandai-Namco-Research-Motiondataset-2/data/"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--zip", default=os.path.join("..", "shared", "datasets", "bandai-namco-2.zip"))
    ap.add_argument("--out", default=".gpu")
    ap.add_argument("--part", type=int, choices=(1, 2), nargs="*", default=[1, 2])
    ap.add_argument("--piece", type=float, default=27.0, help="MiB per piece (one call's share)")
    a = ap.parse_args()
    pack(a)
    parts = [os.path.join(a.out, f"p{i}", f"part{i}.tar.xz") for i in (1, 2)]
    if all(os.path.exists(p) for p in parts) and sorted(a.part) in ([], [1, 2]):
        cut(parts, a.out, int(a.piece * 2**20))


def cut(parts: list[str], out: str, piece: int) -> None:
    """The archives, one after the other, in pieces of at most ``piece`` bytes: ``out/c<k>/bn2.<k>`` + ``pieces.txt``."""
    blob = b"".join(open(p, "rb").read() for p in parts)
    n = -(-len(blob) // piece)
    rows = [f"{n}\n"] + [f"{os.path.basename(p)}\t{os.path.getsize(p)}\t{hashlib.sha1(open(p, 'rb').read()).hexdigest()}\n"
                         for p in parts]
    for k in range(n):
        d = os.path.join(out, f"c{k + 1}")
        os.makedirs(d, exist_ok=True)
        with open(os.path.join(d, f"bn2.{k + 1}"), "wb") as f:
            f.write(blob[k * piece:(k + 1) * piece])
        with open(os.path.join(d, "pieces.txt"), "w") as f:
            f.writelines(rows)
        print(f"{d}: piece {k + 1} of {n}, {os.path.getsize(os.path.join(d, f'bn2.{k + 1}')) / 2**20:.1f} MiB")


def pack(a: argparse.Namespace) -> None:
    with zipfile.ZipFile(a.zip) as z:
        names = sorted(n for n in z.namelist() if n.startswith(PFX) and n.endswith(".bvh"))
        for part in a.part:
            t0 = time.time()
            mine = names[part - 1::2]
            dst = os.path.join(a.out, f"p{part}", f"part{part}.tar.xz")
            os.makedirs(os.path.dirname(dst), exist_ok=True)
            with lzma.open(dst + ".tmp", "wb", preset=9 | lzma.PRESET_EXTREME) as xz, tarfile.open(fileobj=xz, mode="w") as t:
                for n in mine:
                    data = z.read(n)
                    info = tarfile.TarInfo(n)
                    info.size = len(data)
                    t.addfile(info, io.BytesIO(data))
                if part == 2:  # the manifest of both parts
                    rows = []
                    for n in names:
                        data = z.read(n)
                        rows.append(f"{n[len(PFX):]}\t{len(data)}\t{hashlib.sha1(data).hexdigest()}\n")
                    blob = "".join(rows).encode()
                    info = tarfile.TarInfo("bn2_manifest.tsv")
                    info.size = len(blob)
                    t.addfile(info, io.BytesIO(blob))
            os.replace(dst + ".tmp", dst)
            print(f"{dst}: {len(mine)} files, {os.path.getsize(dst) / 2**20:.1f} MiB, {time.time() - t0:.0f} s")


if __name__ == "__main__":
    main()
