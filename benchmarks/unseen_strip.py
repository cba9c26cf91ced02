"""The picture of RESULTS.md section 3.1: one clip of a held-out content filled from keyframes alone, the model,
interpolation and the ground truth side by side (a PNG strip of frames and a GIF), the feet's trails on the floor
thick where a foot is planted (the model's predicted contact if it has contact channels, else the data's rule).

    python benchmarks/unseen_strip.py <checkpoint trained on the content split> [--clip NAME] [--every 30] [--out results/unseen]

The clip comes from the content split's test clips (contents the checkpoint never saw); keys every ``--every``
frames, nothing else known, filled through ``Inbetweener.fill_arrays`` as in ``eval.py protocol=keyframes``.
Prints the clip's mean joint error (cm) of the model and of interpolation over the generated frames."""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    from _report import strip_arguments  # benchmarks/ helper (this script may be imported from elsewhere)

    strip_arguments(ap, "dataset-2_run_active_010", "results/unseen", "test clip name (content split)")
    a = ap.parse_args(argv)

    from inbetweening.api.inbetweener import Inbetweener
    from inbetweening.data.contacts import CONTACT_THRESHOLD as THRESHOLD
    from inbetweening.data.contacts import planted_frames
    from inbetweening.data.datasets import load_dataset
    from inbetweening.evaluation import keyframes as KF
    from inbetweening.evaluation.schedules import keyframe_indices
    from inbetweening.geometry.interp import interpolate_keyframes
    from inbetweening.rendering.render import render_gif, render_png

    data = load_dataset("bandai_namco", a.data, split="content")
    clip = next((c for c in data.test if Path(str(c.name)).stem == a.clip), None)
    if clip is None:
        raise SystemExit(f"--clip: no test clip {a.clip!r} in the content split (e.g. {data.test[0].name})")
    n = min(a.frames, len(clip.root_pos))
    keys = keyframe_indices(n, a.every)
    (root, q), (root_in, q_in), gen = KF.keyed_clip(clip.root_pos, clip.local_q, keys)
    n = len(root)
    *model, contact = Inbetweener.from_checkpoint(a.ckpt).fill_arrays(root_in, q_in, keys, with_contacts=True)
    interp = interpolate_keyframes(root_in, q_in, keys)
    sk = data.skeleton
    pos = {name: sk.pose(*motion)[1] for name, motion in
           (("model", model), ("interpolation", interp), ("ground truth", (root, q)))}
    # the feet's trails, thick where planted: the model's predicted contact if it has one, else the data's rule
    feet = list(data.contact.indices(sk.names))
    planted = {name: planted_frames(p[:, feet], data.fps, data.contact.height, data.contact.speed)
               for name, p in pos.items()}
    if contact is not None:
        planted["model"] = np.nan_to_num(contact[:, feet]) > THRESHOLD
    for name in ("model", "interpolation"):
        total, count = KF.position_error(pos[name], pos["ground truth"], gen)
        print(f"{a.clip}, keys every {a.every}: {name} {total / count:.2f} cm")
    highlight = np.zeros(n, bool)
    highlight[keys] = True
    shown = [t for t in range(0, n, max(1, a.every // 3))]
    out = Path(a.out)
    render_png(pos, sk.parents, out.with_suffix(".png"), frames=shown, highlight=highlight,
               title=f"{a.clip}: unseen content, keys every {a.every} frames", feet=feet, contacts=planted)
    render_gif(pos, sk.parents, out.with_suffix(".gif"), fps=15, highlight=highlight, dpi=50,
               title=f"{a.clip}, keys every {a.every}", feet=feet, contacts=planted)
    print(f"wrote {out.with_suffix('.png')} and {out.with_suffix('.gif')}")


if __name__ == "__main__":
    main()
