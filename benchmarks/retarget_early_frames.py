"""The learned retargeter's joint position error by frame index (RESULTS.md section 13).

    python benchmarks/retarget_early_frames.py
"""
# pos_err (% body height) of the learned retargeter by frame index: frames 0-9 against 10 on (held-out walk+run)
import numpy as np
import torch

from inbetweening.data.contacts import body_height
from inbetweening.data.datasets import load_dataset
from inbetweening.retarget.data import select, split_clips
from inbetweening.retarget.learned import LearnedRetarget

torch.set_num_threads(1)

d = load_dataset("bandai_namco", "/work/shared/datasets/bandai-namco-2.zip")
l = LearnedRetarget.from_checkpoint("models/retarget_cmu/model.ckpt")
test = split_clips(select(sorted(d.train + d.test, key=lambda c: c.name), ["walk", "run"]), 0.6)[1]
errs, refs = [], []
for c in test:
    a = l.rig.positions(*l.rig.analytic(c.root_pos, c.local_q))
    lq, lp, _ = l(c.root_pos, c.local_q)
    errs.append(np.linalg.norm(l.rig.positions(lq, lp) - a, axis=-1).mean(-1))
    refs.append(a)
h = body_height(refs)
early = np.concatenate([e[:10] for e in errs]).mean() / h * 100
late = np.concatenate([e[10:] for e in errs]).mean() / h * 100
print(f"{len(test)} clips: frames 0-9 {early:.3f} %, frames 10+ {late:.3f} %")
