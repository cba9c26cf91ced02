"""Fill the frames between keyframes of a BVH clip with a trained model (command line).

Run ``python -m inbetweening.predict --help`` for the usage.
"""
from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from inbetweening.api.shipped import REPO, SHIPPED_CKPTS, SHIPPED_ONNX
from inbetweening.cli.args import UsageError, fail, parse_args, parse_bool, parse_int_list, parse_partial_keys, parse_paths
from inbetweening.runtime.errors import InbetweenError
from inbetweening.runtime.settings import FillSettings

USAGE = """\
usage: python -m inbetweening.predict [ckpt_path=<model.ckpt|.onnx>|[a,b]] input=<clip.bvh> output=<out.bvh>
                                      (keyframes=<list> | gap=<n>) [options]

Fill the frames between keyframes with a trained in-betweening model and write a BVH file with the input's
hierarchy and channel order (it opens in Blender, MotionBuilder, ...).  Every option can be given as
key=value or as --key value.

Two ways to say which frames are keyframes:

  'keyframes=[0,30,75]' (form A) keep these frames of the input clip (at least 2, increasing, any spacing;
                        keyframes=0,30,75 works too) and generate every other frame between the first and
                        the last one.  Frames before the first / after the last keyframe are dropped: the
                        output has last - first + 1 frames and input frame k is output frame k - first.
  gap=30                (form B) every frame of the input is a keyframe (a clip holding only the key poses);
                        30 frames are generated between each consecutive pair, so K input frames give
                        K + (K - 1) * 30 output frames.

Partial keys (with form A): 'partial=45:UpperArm_L,LowerArm_L,Hand_L;60:UpperLeg_R' says that at input frame 45
only the left arm is keyed, at 60 only the right thigh: those bones' values there constrain the fill (the model
was trained for keys known on some bones), the frames' other bones are generated.  Bone names are the input's;
frames lie strictly between the first and the last keyframe.  Their bones' channels are copied unchanged too.

Keyframe rows are copied unchanged into the output.  Generated frames take non-root position channels from
the nearest keyframe; a folded Bandai-Namco joint_Root (still, or carrying the locomotion) moves between its
values at the two surrounding keyframes and Hips gets the generated motion under it (the world motion is the
model's).

Long gaps: the model was trained on transitions of up to a fixed length (printed below as "max gap", from the
checkpoint).  A longer gap is split into equal segments of at most max_gap frames; the poses at the split
points are pseudo-keyframes interpolated between the two surrounding keyframes (root position linearly,
joint rotations by slerp), then the segments are generated left to right, each one using the end of the
previous one as its 10 context frames.  Your keyframes are never changed.  segment=false refuses such gaps.

options:
  ckpt_path=PATH        checkpoint (.ckpt) of an in-betweening model or its exported window graph (.onnx: runs
                        on ONNX Runtime without loading PyTorch; `python -m inbetweening.blender export`), or a
                        list [a.ckpt,b.ckpt] of models of one skeleton filling as an ensemble (their mean);
                        default: the shipped Bandai-Namco-2 ensemble of this repository, SHIPPED_LIST
                        (their checkpoints instead for device=cuda, fill.adapt_steps > 0 or without onnxruntime)
  input=PATH            BVH clip of any humanoid character, the model's own skeleton included (its bones are
                        matched to the model's joints and the keys retargeted, its own skeleton exactly; the
                        map used is printed and saved next to the output as <output>.bone_map.yaml) (required)
  bone_map=PATH         a bone map override (YAML, `rig_bone: slot` per line) for what detection gets wrong;
                        a saved <output>.bone_map.yaml is one
  output=PATH           BVH file to write                                                (required)
  keyframes=LIST        form A, see above
  partial=F:BONES;...   partial keys (form A), see above
  gap=N                 form B, see above
  max_gap=N             longest gap generated in one pass (default: the longest gap the model was trained on)
  segment=true|false    split gaps longer than max_gap (default true; --no-segment = false)
  foot_lock=true|false  hold a foot still where the model predicts it planted, the leg solved by IK (default true,
                        for models that predict contacts; --no-foot-lock = false: the network's output as it is)
  self_check=true|false scale the network's share of each gap by how well it predicts your own keys when each is
                        hidden in turn (default true: falls back to interpolation on motions the model does not know;
                        false: the calibrated weight per gap length alone)
  fill.NAME=VALUE       one of the fill's tuned numbers (listed below with its default and the evidence it was
                        chosen on; the defaults are the shipped fill's)
  render=PATH.gif|.png  also write a picture: the result next to plain linear interpolation of the same
                        keyframes, keyframes drawn in red, over a floor with the feet's trails (thick where a foot
                        is planted: a sliding foot draws a streak); .gif an animation following the body, .png a
                        filmstrip of 8 frames
  render_dpi=N          picture resolution (default 80)
  device=cpu|cuda       where the model runs (default cpu)
  threads=N             CPU threads of the network (default 1: one transition is too small to share between
                        threads, and spare threads only wait on each other on a busy machine)
  --force               allow output (or render) to be the input file itself (refused otherwise)
  -h, --help            show this help

the fill's tuned numbers (inbetweening.runtime.settings.FillSettings):
FILL_SETTINGS

examples:
  python -m inbetweening.predict ckpt_path=run/checkpoints/last.ckpt input=walk.bvh 'keyframes=[0,30,75]' \\
      output=walk_filled.bvh
  python -m inbetweening.predict --ckpt_path run/last.ckpt --input keys.bvh --gap 30 --output out.bvh \\
      --render out.gif
"""

OPTIONS = {
    "ckpt_path": parse_paths, "input": str, "output": str, "keyframes": parse_int_list, "partial": parse_partial_keys,
    "gap": int, "max_gap": int, "segment": parse_bool, "foot_lock": parse_bool, "self_check": parse_bool,
    "render": str, "render_dpi": int, "device": str, "force": parse_bool,
    "threads": int, "bone_map": str,
}
OPTIONS.update({f"fill.{name}": float for name in FillSettings.__dataclass_fields__})  # checked by FillSettings
ALIASES = {"ckpt": "ckpt_path", "checkpoint": "ckpt_path", "in": "input", "out": "output", "o": "output",
           "keys": "keyframes"}


RENDER_FORMATS = (".gif", ".png")  # render=PATH: an animation, or a filmstrip of 8 frames


def render_comparison(result, path: str | Path, fps: float, dpi: int = 80, contact=None) -> Path:
    """A picture of a :class:`~inbetweening.api.inbetweener.FillResult`, prediction | linear interpolation, keys in
    red, in the format the file name says: ``.gif`` an animation, ``.png`` a filmstrip (ValueError otherwise).

    ``contact``: the model's feet and contact rule (:class:`~inbetweening.data.contacts.FootContact`, the
    predictor's ``contact``; one without feet, or ``None``: found from the skeleton's joint names or shape, the rule
    scaled to its height): the feet's trails are drawn on the floor, thick where a foot is planted, so a sliding
    foot draws a streak.  Planted: the model's predicted contact where it has one (``result.contact``), else the
    rule on the drawn motion (``fps`` frames per second); interpolation: the rule."""
    from inbetweening.data.contacts import CONTACT_THRESHOLD as THRESHOLD
    from inbetweening.data.contacts import body_height, find_feet, planted_frames, scaled_contact
    from inbetweening.data.errors import DatasetError
    from inbetweening.rendering.render import render_gif, render_png

    suffix = Path(path).suffix.lower()
    if suffix not in RENDER_FORMATS:
        raise ValueError(f"{path} must end in .gif (an animation) or .png (a filmstrip)")

    skel = result.skeleton
    ir, iq = result.interpolation()
    _, lerp = skel.pose(ir, iq)
    highlight = np.zeros(result.num_frames, dtype=bool)
    highlight[result.known_frames] = True
    seqs = {"model": result.global_positions(), "linear interpolation": lerp}
    title = Path(path).stem
    if contact is None or not contact.feet:  # a model trained before it recorded its data's feet
        gt = seqs["model"]
        found, _ = find_feet(skel.names, skel.parents, np.median(gt[..., 1], axis=0))
        contact = scaled_contact(found, body_height([gt]))
    try:
        feet = list(contact.indices(skel.names))
    except DatasetError:  # the model's feet are not in this skeleton: no trails
        feet = []
    kw: dict = {}
    if feet:
        planted = {label: planted_frames(pos[:, feet], fps, contact.height, contact.speed)
                   for label, pos in seqs.items()}
        if result.contact is not None:
            planted["model"] = np.nan_to_num(result.contact[:, feet]) > THRESHOLD
            title += "  (planted: the model's prediction | the contact rule)"
        kw = {"feet": feet, "contacts": planted}
    if suffix == ".png":
        return render_png(seqs, skel.parents, path, dpi=dpi, highlight=highlight, title=title, **kw)
    return render_gif(seqs, skel.parents, path, fps=int(max(1, min(round(fps), 50))), highlight=highlight,
                      dpi=dpi, title=title, **kw)


SHIPPED_MODELS = tuple(REPO / c for c in SHIPPED_ONNX)  # the shipped ensemble's window graphs (no PyTorch)
SHIPPED_CHECKPOINTS = tuple(REPO / c for c in SHIPPED_CKPTS)  # the same models as trained
USAGE = USAGE.replace("SHIPPED_LIST", f"[{','.join(SHIPPED_ONNX)}]")  # one list: api/shipped.py
USAGE = USAGE.replace("FILL_SETTINGS", FillSettings.describe())


def default_checkpoint(torch: bool = False) -> list[str] | None:
    """The shipped ensemble (:mod:`inbetweening.api.shipped`: ``models/bn2_partial``, ``models/bn2_partial_twin`` and
    ``models/bn2_v2`` of a source checkout): their window graphs (``model.onnx``, filled on ONNX Runtime), or their
    checkpoints where ``torch`` (the fill needs PyTorch: another device, test-time adaptation) or ONNX Runtime is not
    installed; ``None`` when absent (an installed package without the repository)."""
    import importlib.util

    graphs = not torch and importlib.util.find_spec("onnxruntime") is not None
    for paths in ((SHIPPED_MODELS, SHIPPED_CHECKPOINTS) if graphs else (SHIPPED_CHECKPOINTS,)):
        if all(p.is_file() for p in paths):
            return [str(p) for p in paths]
    return None


def run(argv: Sequence[str]) -> int:
    try:
        args = parse_args(argv, OPTIONS, ALIASES)
    except UsageError as e:
        fail(e)
    if args is None:
        print(USAGE)
        return 0
    device = args.get("device", "cpu")
    needs_torch = device != "cpu" or args.get("fill.adapt_steps", 0) > 0
    shipped = "ckpt_path" not in args and default_checkpoint(needs_torch) is not None
    if shipped:
        args["ckpt_path"] = default_checkpoint(needs_torch)
    missing = [k for k in ("ckpt_path", "input", "output") if k not in args]
    if missing:
        fail(f"missing {', '.join(f'{k}=...' for k in missing)} (see --help)")
    if ("keyframes" in args) == ("gap" in args):
        fail("give exactly one of keyframes=[...] (frames of the input to keep) or gap=N (frames to generate "
             "between consecutive input frames); see --help")

    if not Path(args["input"]).is_file():  # checked before torch is imported: a typo costs no start-up
        fail(f"input: {args['input']} does not exist")
    from inbetweening.atomic import same_file

    models = args["ckpt_path"] if isinstance(args["ckpt_path"], list) else [args["ckpt_path"]]
    for key in ("output", "render"):
        for src, path in [("input", args["input"])] + [("ckpt_path", m) for m in models]:
            if key in args and same_file(path, args[key]) and not args.get("force", False):
                fail(f"{key}: {args[key]} is the {src} file; writing it would destroy the {src} "
                     f"(choose another {key}, or --force to overwrite)")
    if "render" in args and Path(args["render"]).suffix.lower() not in RENDER_FORMATS:  # before any work is done
        fail(f"render: {args['render']} must end in .gif (an animation) or .png (a filmstrip)")
    if args.get("threads", 1) < 1:
        fail(f"threads: must be >= 1, got {args['threads']}")
    try:  # before any work is done
        settings = FillSettings.from_mapping({k[5:]: v for k, v in args.items() if k.startswith("fill.")})
    except InbetweenError as e:
        fail(e)
    from inbetweening.api.inbetweener import Inbetweener
    from inbetweening.data.bvh import BVHError, read_bvh
    from inbetweening.data.bvh_writer import write_bvh
    from inbetweening.runtime.model import ModelError

    errors = (InbetweenError, ModelError, BVHError, OSError)
    if any(not str(m).lower().endswith(".onnx") for m in models):  # a checkpoint: PyTorch runs it
        import torch

        from inbetweening.predictor.checkpoint import CheckpointError

        errors += (CheckpointError,)
        if str(device).startswith("cuda") and not torch.cuda.is_available():
            fail(f"device: {device} requested but CUDA is not available (use device=cpu)")
        torch.set_num_threads(args.get("threads", 1))
    elif device != "cpu":
        fail(f"device: {device} runs checkpoints (.ckpt); an exported .onnx model runs on the CPU (use device=cpu)")
    t0 = time.perf_counter()
    try:
        clip = read_bvh(args["input"])
        kw = {k: args[k] for k in ("max_gap", "segment", "foot_lock", "self_check") if k in args}
        kw["settings"] = settings
        ib = Inbetweener.from_checkpoint(args["ckpt_path"], device=device, threads=args.get("threads", 1), **kw)
        out = Path(args["output"])
        try:
            res = ib.fill_detailed(clip, keyframes=args.get("keyframes"), gap=args.get("gap"),
                                   bone_map=args.get("bone_map"), partial=args.get("partial"))
        except InbetweenError as e:
            template = getattr(e, "template", None)
            if template:  # a rig that cannot be mapped: an override template to fill in, next to the output
                path = out.with_name(out.name + ".bone_map.yaml")
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_text(template)
                fail(f"{e} (an override template: {path}; pass it back with bone_map={path})")
            raise
        out.parent.mkdir(parents=True, exist_ok=True)
        write_bvh(res.bvh, out)
        if res.bone_map is not None:
            saved = out.with_name(out.name + ".bone_map.yaml")
            saved.write_text(res.bone_map.to_yaml())
            print(f"{clip.source}: another skeleton than the model's; bone map (saved to {saved}):")
            print(res.bone_map.summary())
    except errors as e:
        fail(e)
    n_gen = res.num_frames - len(res.known_frames)
    msg = (f"wrote {out}: {res.num_frames} frames ({len(res.known_frames)} keyframes, {n_gen} generated; "
           f"max gap {ib.max_gap}")
    if res.pseudo_keyframes:
        msg += f"; long gaps split at frames {res.pseudo_keyframes}"
    print(msg + f") in {time.perf_counter() - t0:.1f} s")
    if shipped:
        print(f"model: the ensemble of {', '.join(models)} (the shipped Bandai-Namco-2 models; ckpt_path=... chooses "
              "another)")
    if "render" in args:
        try:
            fps = 1.0 / res.bvh.frame_time if res.bvh.frame_time > 0 else ib.fps
            picture = render_comparison(res, args["render"], fps, dpi=args.get("render_dpi", 80),
                                        contact=ib.runtime.info.contact)
        except (OSError, ValueError) as e:
            fail(f"render: {e}")
        print(f"wrote {picture}")
    return 0


def main() -> None:
    sys.exit(run(sys.argv[1:]))


if __name__ == "__main__":
    main()
