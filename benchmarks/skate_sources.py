"""Where the fill's foot skating comes from (RESULTS.md section 12.10): the keyframes-only protocol's skating (the
horizontal speed of each foot joint where the ground truth's is planted) split by what the fill's own contact said
there, per foot joint.

    python benchmarks/skate_sources.py <checkpoint>[,<checkpoint>...] <split> [clips, default 30] [schedules, default 15,45]

Categories of a scored (frame pair, foot joint) where the real foot is planted: ``locked`` (the fill held the joint
at both frames: its contact above one half), ``edge`` (at one of the two), ``blend`` (within 4 frames of a held
frame: the lock's blend) and ``free`` (the fill did not plant it).  Per category and joint: its share of the
entries, its mean speed (cm/s) and its share of the skating.  Keys count as held.  Fills with the fill's defaults
(the self-check, the feet locked), ``clips`` test clips evenly spaced.
"""
from __future__ import annotations

import sys

import numpy as np
import torch

from inbetweening.data.contacts import foot_contacts
from inbetweening.data.datasets import load_dataset
from inbetweening.evaluation import keyframes as KF
from inbetweening.evaluation.schedules import schedule_keyframes
from inbetweening.runtime import FillRuntime
from inbetweening.runtime.ensemble import EnsembleBackend
from inbetweening.runtime.foot_lock import CONTACT_THRESHOLD
from inbetweening.runtime.settings import DEFAULT_SETTINGS
from inbetweening.runtime.torch_backend import TorchBackend


def categories(contact: np.ndarray, generated: np.ndarray) -> dict[str, np.ndarray]:
    """``contact (F, K)`` the fill's contact of the foot joints, ``generated (F,)`` -> ``{category: (F-1, K) bool}``."""
    held = np.nan_to_num(contact, nan=0.0) > CONTACT_THRESHOLD
    held[~generated] = True
    both, one = held[:-1] & held[1:], held[:-1] ^ held[1:]
    near = np.zeros_like(held)
    for d in range(1, DEFAULT_SETTINGS.blend_frames + 1):
        near[d:] |= held[:-d]
        near[:-d] |= held[d:]
    blend = (near[:-1] | near[1:]) & ~both & ~one
    return {"locked": both, "edge": one, "blend": blend, "free": ~(both | one | blend)}


def main() -> None:
    torch.set_num_threads(1)
    paths = sys.argv[1].split(",")
    split = sys.argv[2]
    n = int(sys.argv[3]) if len(sys.argv) > 3 else 30
    schedules = [int(k) if k.isdigit() else k for k in (sys.argv[4] if len(sys.argv) > 4 else "15,45").split(",")]
    members = [TorchBackend.from_checkpoint(p) for p in paths]
    runtime = FillRuntime(EnsembleBackend(members, paths) if len(members) > 1 else members[0])
    data = load_dataset("bandai_namco", split=split)
    sk, fps = data.skeleton, data.fps
    feet = KF.foot_spec(sk, data.contact)
    joints = list(feet.joints)
    clips = [data.test[i] for i in np.linspace(0, len(data.test) - 1, min(n, len(data.test))).round().astype(int)]
    for schedule in schedules:
        sums: dict = {}
        for i, clip in enumerate(clips):
            gt_pos = sk.pose(np.asarray(clip.root_pos, np.float64), np.asarray(clip.local_q, np.float64))[1]
            keys = schedule_keyframes(schedule, len(clip.root_pos), np.random.default_rng(i), gt_pos)
            if len(keys) < 2:
                continue
            end = keys[-1] + 1
            root, q = np.array(clip.root_pos[:end], np.float64), np.array(clip.local_q[:end], np.float64)
            generated = np.ones(end, dtype=bool)
            generated[keys] = False
            root[generated], q[generated] = np.nan, np.nan
            out = runtime.fill(root, q, keys)
            planted = foot_contacts(gt_pos[:end, joints], fps, feet.contact_height, feet.contact_speed)
            planted &= KF.scored_pairs(generated)[:, None]
            speed = KF.horizontal_speed(sk.pose(out.root, out.local_q)[1][:, joints], fps)
            for name, where in categories(out.contact[:, joints], generated).items():
                for k, j in enumerate(joints):
                    sel = planted[:, k] & where[:, k]
                    total = sums.setdefault((name, sk.names[j]), [0.0, 0])
                    total[0] += float(speed[sel, k].sum())
                    total[1] += int(sel.sum())
        count = sum(c for _, c in sums.values())
        skate = sum(s for s, _ in sums.values())
        print(f"\nkeys {schedule}: skating {skate / max(count, 1):.2f} cm/s over {count} entries")
        print("| category | joint | share of the entries | mean speed, cm/s | share of the skating |")
        print("|---|---|---:|---:|---:|")
        for (name, joint), (s, c) in sorted(sums.items()):
            print(f"| {name} | {joint} | {c / max(count, 1):.3f} | {s / max(c, 1):.2f} | {s / max(skate, 1e-9):.3f} |")


if __name__ == "__main__":
    main()
