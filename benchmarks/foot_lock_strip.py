"""The picture of foot locking: one Bandai-Namco-2 test clip filled from keyframes alone, with the feet locked where
the model predicts them planted, without, and the ground truth, side by side (a PNG strip of frames).

    python benchmarks/foot_lock_strip.py <checkpoint> [--clip NAME] [--every 30] [--out results/foot_lock.png]

Any checkpoint whose data names its feet: the contact is the model's prediction where its representation has contact
channels, else the data's contact rule on the fill (the fill runtime's).  Keys
every ``--every`` frames, nothing else known, filled through ``Inbetweener.fill_arrays`` with ``foot_lock=True`` and
``foot_lock=False`` (the same network output: only the lock differs).  The feet's paths are drawn on the floor,
thick where a foot is planted (the contact the lock used; the ground truth: the data's contact rule): a planted
foot that holds still is a dot, one that slides a streak.  Prints each motion's foot skating (cm/s of horizontal foot
speed where the ground truth's feet are planted, as ``eval.py protocol=keyframes`` scores it)."""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

LABELS = ("foot lock", "no foot lock", "ground truth")


def fill_both(ib, root: np.ndarray, q: np.ndarray, keys: list[int]) -> dict[str, tuple]:
    """``label -> (root (F, 3), local_q (F, J, 4), planted contact (F, J) or None)``: the clip filled from ``keys``
    with and without foot locking (the model's predicted contact with both), and the ground truth (no contact:
    the caller applies the data's rule)."""
    from inbetweening.evaluation import keyframes as KF

    _, (root_in, q_in), _ = KF.keyed_clip(root, q, keys)
    out = {}
    for label, lock in zip(LABELS[:2], (True, False)):
        out[label] = ib.fill_arrays(root_in, q_in, keys, foot_lock=lock, with_contacts=True)
        if out[label][2] is None:
            raise SystemExit("the checkpoint's data names no feet: nothing to lock")
    out[LABELS[2]] = (root, q, None)
    return out


def draw(ib, root: np.ndarray, q: np.ndarray, every: int, title: str, fps: float | None = None, shown: int = 10):
    """``(figure, skate)``: the three panels of a clip ``root (F, 3), local_q (F, J, 4)`` (cut after its last key)
    filled from keys every ``every`` frames, ``shown`` poses of each drawn; ``skate``: label -> foot skating (cm/s)
    over the generated frames where the ground truth's feet are planted."""
    from inbetweening.data.contacts import CONTACT_THRESHOLD as THRESHOLD
    from inbetweening.data.contacts import foot_contacts, planted_frames
    from inbetweening.evaluation import keyframes as KF
    from inbetweening.evaluation.schedules import keyframe_indices
    from inbetweening.rendering.skeleton_plot import draw_sequences

    fps = float(fps or ib.fps)
    keys = keyframe_indices(len(root), every)
    if not keys:
        raise SystemExit(f"the clip has {len(root)} frames: too short for keys every {every} frames")
    n = keys[-1] + 1
    root, q = np.asarray(root[:n], np.float64), np.asarray(q[:n], np.float64)
    motions = fill_both(ib, root, q, keys)
    sk, contact = ib.skeleton, ib.predictor.contact
    feet = list(contact.indices(sk.names, "the model's feet"))
    pos = {label: sk.pose(r, lq)[1] for label, (r, lq, _) in motions.items()}
    planted = {label: (np.nan_to_num(c[:, feet]) > THRESHOLD if c is not None else
                       planted_frames(pos[label][:, feet], fps, contact.height, contact.speed))
               for label, (_, _, c) in motions.items()}
    gt_contact = foot_contacts(pos[LABELS[2]][:, feet], fps, contact.height, contact.speed)
    gt_contact &= KF.scored_pairs(KF.generated_frames(n, keys))[:, None]
    skate = {}
    for label, p in pos.items():
        total, count = KF.foot_skate(p[:, feet], gt_contact, fps)
        skate[label] = total / count if count else 0.0
    highlight = np.zeros(n, dtype=bool)
    highlight[keys] = True
    frames = sorted({round(t) for t in np.linspace(0, n - 1, min(shown, n))})
    named = {f"{label}: skate {skate[label]:.1f} cm/s": p for label, p in pos.items()}
    fig = draw_sequences(named, sk.parents, frames=frames, highlight=highlight, title=title, feet=feet,
                         contacts=dict(zip(named, planted.values())))
    return fig, skate


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    from _report import strip_arguments  # benchmarks/ helper (this script may be imported from elsewhere)

    strip_arguments(ap, "dataset-2_walk_normal_010", "results/foot_lock.png", "test clip name (without .bvh)")
    a = ap.parse_args(argv)

    from inbetweening.api.inbetweener import Inbetweener
    from inbetweening.data.datasets import load_dataset

    data = load_dataset("bandai_namco", path=a.data)
    clip = next((c for c in data.test if Path(str(c.name)).stem == a.clip), None)
    if clip is None:
        raise SystemExit(f"--clip: no test clip {a.clip!r} (e.g. {Path(str(data.test[0].name)).stem})")
    ib = Inbetweener.from_checkpoint(a.ckpt)
    n = min(a.frames, len(clip.root_pos))
    fig, skate = draw(ib, clip.root_pos[:n], clip.local_q[:n], a.every,
                      f"{a.clip}: keys every {a.every} frames, foot lock | none | ground truth", fps=data.fps)
    for label, v in skate.items():
        print(f"{a.clip}, keys every {a.every}: {label}: foot skating {v:.2f} cm/s")
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, format="png", dpi=100)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
