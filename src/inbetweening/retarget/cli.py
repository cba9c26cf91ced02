"""Retarget a BVH clip of the source skeleton onto the target rig of a learned retargeter (command line).

Run ``python -m inbetweening.retarget --help`` for the usage.
"""
from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from pathlib import Path

from inbetweening.api.shipped import REPO
from inbetweening.cli.args import UsageError, fail, parse_args, parse_bool

USAGE = """\
usage: python -m inbetweening.retarget [ckpt_path=<retarget.ckpt>] input=<source.bvh> output=<out.bvh>
                                       [target_rig=<rig.bvh>] [method=learned|analytic] [threads=<n>]

Carry a motion of the source skeleton (the skeleton the checkpoint was trained on, e.g. a Bandai-Namco-2 take; a
top joint such as joint_Root is folded into the hips) onto the target rig the checkpoint was trained for, and write
a BVH file with the target rig's hierarchy and channel order.  The checkpoint is one of
`python train.py task=retarget target_rig=<rig.bvh> ...` (default: models/retarget_cmu/model.ckpt, the CMU
skeleton, trained on Bandai-Namco-2 walking and running: CC BY-NC 4.0 data).

  target_rig=<rig.bvh>   optional: checked to be the rig the checkpoint was trained for (hierarchy: names, parents)
  method=analytic        the analytic retargeter (the network's training target) instead of the network
  threads=1              torch threads
"""

DEFAULT_CKPT = REPO / "models" / "retarget_cmu" / "model.ckpt"
OPTIONS = {"ckpt_path": str, "input": str, "output": str, "target_rig": str, "method": str, "threads": int,
           "quiet": parse_bool}


def run(opts: dict) -> Path:
    """Retarget ``opts["input"]`` and write ``opts["output"]``; one-line errors as :class:`UsageError`."""
    import torch

    from inbetweening.data.bvh import BVHError, read_bvh
    from inbetweening.data.bvh_writer import write_bvh
    from inbetweening.data.clips import clip_in_skeleton
    from inbetweening.data.errors import DatasetError
    from inbetweening.predictor.checkpoint import CheckpointError
    from inbetweening.retarget.learned import LearnedRetarget, check_target
    from inbetweening.runtime.model import InbetweenError

    for key in ("input", "output"):
        if not opts.get(key):
            raise UsageError(f"{key}: required (see --help)")
    src, out = Path(opts["input"]), Path(opts["output"])
    if out.resolve() == src.resolve():
        raise UsageError(f"output: {out} is the input file; choose another path")
    method = opts.get("method", "learned")
    if method not in ("learned", "analytic"):
        raise UsageError(f"method: {method!r}; choose learned or analytic")
    if opts.get("threads"):
        torch.set_num_threads(int(opts["threads"]))
    ckpt = Path(opts.get("ckpt_path") or DEFAULT_CKPT)
    try:
        if not src.is_file():
            raise UsageError(f"input: {src} is not a file")
        if not ckpt.is_file():
            raise UsageError(f"ckpt_path: {ckpt} is not a file")
        learned = LearnedRetarget.from_checkpoint(ckpt)
        rig = learned.rig
        if opts.get("target_rig"):
            if not Path(opts["target_rig"]).is_file():
                raise UsageError(f"target_rig: {opts['target_rig']} is not a file")
            check_target(rig, read_bvh(opts["target_rig"]), "target_rig", str(ckpt))
        bvh = read_bvh(src)
        try:
            _, root, q = clip_in_skeleton(bvh, rig.source)
        except DatasetError as e:
            raise UsageError(f"input: {e}") from None
        if len(root) < 4:
            raise UsageError(f"input: {src} has {len(root)} frames; at least 4 are needed")
        t0 = time.perf_counter()
        if method == "learned":
            lq, lp, _ = learned(root, q)
        else:
            lq, lp = rig.analytic(root, q)
        seconds = time.perf_counter() - t0
        out.parent.mkdir(parents=True, exist_ok=True)
        write_bvh(rig.bvh.with_motion(lq, lp, bvh.frame_time), out)
    except (BVHError, CheckpointError, InbetweenError) as e:
        raise UsageError(str(e)) from None
    if not opts.get("quiet"):
        print(f"{src} ({len(root)} frames, {rig.source.num_joints} joints) -> {out} ({rig.skeleton.num_joints} joints, "
              f"{method}, {1000 * seconds / len(root):.3f} ms per frame)")
    return out


def main(argv: Sequence[str] | None = None) -> None:
    try:
        opts = parse_args(sys.argv[1:] if argv is None else argv, OPTIONS)
        if opts is None:
            print(USAGE)
            return
        run(opts)
    except UsageError as e:
        fail(str(e))
