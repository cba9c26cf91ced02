"""The committed reference model (models/bn2_reference) loads alone, fills real Bandai-Namco clips, and (slow)
reproduces its reported benchmark."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from inbetweening import Inbetweener
from inbetweening.data.bvh import iter_bvh_sources, parse_bvh
from inbetweening.data.datasets import bandai_namco_split, fold_static_root
from inbetweening.geometry.interp import interpolate_keyframes
from inbetweening.training.module import InbetweenModule

ROOT = Path(__file__).resolve().parents[1]
CKPT = ROOT / "models" / "bn2_reference" / "model.ckpt"
BN2 = ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"
needs_bn2 = pytest.mark.skipif(not BN2.exists(), reason=f"Bandai-Namco-2 not found at {BN2}")


CONTENT_CKPT = ROOT / "models" / "bn2_content" / "model.ckpt"
PARTIAL_CKPT = ROOT / "models" / "bn2_partial" / "model.ckpt"
PARTIAL_TWIN_CKPT = ROOT / "models" / "bn2_partial_twin" / "model.ckpt"


@pytest.mark.parametrize("path", [CKPT, CONTENT_CKPT, PARTIAL_CKPT, PARTIAL_TWIN_CKPT],
                         ids=["bn2_reference", "bn2_content", "bn2_partial", "bn2_partial_twin"])
def test_shipped_models_load_without_training_state_and_carry_the_blend(path):
    ckpt = torch.load(path, map_location="cpu", weights_only=False)
    assert "optimizer_states" not in ckpt and "lr_schedulers" not in ckpt
    m = InbetweenModule.load_from_checkpoint(path, map_location="cpu")
    assert m.hparams.dataset == "bandai_namco" and m.skeleton.num_joints == 21 and m.skeleton.names[0] == "Hips"
    assert m.hparams.model["name"] == "graph_transformer" and m.hparams.model["depth"] == 6
    # the do-no-harm blend fitted on the validation windows (RESULTS.md section 5.1): one weight per gap length 1-54
    # (the longest gap a 65-frame window holds; the bn2_partial* fits after training: up to its data's transition_max, 45,
    # longer gaps take the last weight), near interpolation for 1-frame gaps, near the network's from 15 on
    blend = list(m.hparams.blend)
    assert len(blend) in (45, 54) and all(0.0 <= w <= 1.0 for w in blend) and blend[0] <= 0.25 and min(blend[14:]) >= 0.85
    rows = ckpt["blend_fit"]["rows"]
    assert [r["weight"] for r in rows] == blend
    assert all(r["blended"] <= min(r["network"], r["interpolation"]) + 1e-12 for r in rows)


@needs_bn2
def test_reference_model_fills_real_test_clips(tmp_path):
    """Fill between every 30th frame of a few real test clips: keyframes exact, the mean joint error below
    interpolation's (the keyframes-only protocol on all test clips: 0.597 of it, RESULTS.md section 2.2)."""
    inb = Inbetweener.from_checkpoint(CKPT)
    sk = inb.module.skeleton
    errs = {"model": [], "interpolation": []}
    clips = [(n, raw) for n, raw in iter_bvh_sources(BN2) if bandai_namco_split(n) == "test"][:6]
    for name, raw in clips:
        bvh = parse_bvh(raw, name)
        clip, _ = fold_static_root(bvh, name)
        f = (min(clip.num_frames, 121) - 1) // 30 * 30 + 1  # keyframes every 30 frames, last frame a keyframe
        keys = list(range(0, f, 30))
        root, q = clip.root_pos[:f], clip.local_q[:f]
        _, gt = sk.fk(q, sk.local_positions(root))
        unknown = np.setdiff1d(np.arange(f), keys)
        for label, (r, qq) in (("model", inb.fill_arrays(root, q, keys)),
                               ("interpolation", interpolate_keyframes(root, q, keys))):
            _, gp = sk.fk(qq, sk.local_positions(r))
            errs[label].append(np.linalg.norm(gp[unknown] - gt[unknown], axis=-1).mean())
        out = inb.fill(bvh, keyframes=keys)  # the BVH path too: keyframe rows exact
        assert all(np.array_equal(out.motion[k], bvh.motion[k]) for k in keys)
    assert np.isfinite(errs["model"]).all()
    # the previous model (RESULTS.md, appendix A.1) already passed: 9.89 cm vs 10.06 cm on these 6 clips
    assert np.mean(errs["model"]) <= 0.99 * np.mean(errs["interpolation"]), errs


@pytest.mark.slow
@needs_bn2
@pytest.mark.parametrize("name,split", [("bn2_reference", "standard"), ("bn2_content", "content"),
                                        ("bn2_v2", "standard"), ("bn2_v2_content", "content"),
                                        ("bn2_partial", "standard"), ("bn2_partial_twin", "standard")])
def test_eval_reproduces_reported_benchmark(name, split, tmp_path):
    import subprocess
    import sys

    ckpt = ROOT / "models" / name / "model.ckpt"
    r = subprocess.run([sys.executable, "eval.py", f"ckpt_path={ckpt}", "data=bandai_namco", f"data.path={BN2}",
                        f"data.split={split}", f"hydra.run.dir={tmp_path}"], cwd=ROOT, capture_output=True, text=True,
                       timeout=1800)
    assert r.returncode == 0, r.stderr[-2000:]
    got = json.loads((tmp_path / "benchmark.json").read_text())["metrics"]
    want = json.loads((ROOT / "results" / f"{name}_benchmark.json").read_text())["metrics"]
    assert got == pytest.approx(want, abs=1e-6)


V2_CKPT = ROOT / "models" / "bn2_v2" / "model.ckpt"
V2_CONTENT_CKPT = ROOT / "models" / "bn2_v2_content" / "model.ckpt"


@pytest.mark.parametrize("path,step", [(V2_CKPT, 4800), (V2_CONTENT_CKPT, 3600)], ids=["bn2_v2", "bn2_v2_content"])
def test_model_v2_predicts_contacts_and_carries_the_blend(path, step):
    """models/bn2_v2 and its content-split companion (RESULTS.md section 2.2): inference-only, the best validation's
    step (model cards), foot contact channels, the do-no-harm blend up to the trained 45-frame gap; the Inbetweener
    locks feet by default."""
    ckpt = torch.load(path, map_location="cpu", weights_only=False)
    assert "optimizer_states" not in ckpt and ckpt["global_step"] == step
    ib = Inbetweener.from_checkpoint(path)
    assert ib.predictor.representation.name == "global_pos_local_quat_contact" and ib.foot_lock
    assert ib.skeleton.num_joints == 21 and ib.predictor.model_cfg["gate"] is True
    blend = list(ib.predictor.blend)
    assert len(blend) == 45 and all(0.0 <= w <= 1.0 for w in blend) and blend[0] < blend[-1]


@needs_bn2
def test_model_v2_locks_only_the_legs_of_generated_frames():
    """A real test clip filled from keys every 30 frames with and without foot locking: keys bit-exact in both, and
    the lock changes only hip, knee and ankle rotations of generated frames (never the root or the upper body; the
    first gap shows it: later gaps take the locked gaps before them as context)."""
    from inbetweening.runtime.foot_lock import legs

    ib = Inbetweener.from_checkpoint(V2_CKPT)
    sk = ib.skeleton
    name, raw = next((n, r) for n, r in iter_bvh_sources(BN2) if bandai_namco_split(n) == "test" and "walk" in n)
    clip, _ = fold_static_root(parse_bvh(raw, name), name)
    keys = list(range(0, 91, 30))
    root, q = clip.root_pos[:91], clip.local_q[:91]
    (r1, q1), (r0, q0) = (ib.fill_arrays(root, q, keys, foot_lock=lock) for lock in (True, False))
    assert np.array_equal(r1[keys], root[keys]) and np.array_equal(q1[keys], q[keys])
    assert np.array_equal(r1[:31], r0[:31])
    leg = sorted({j for chain in legs(sk, list(ib.predictor.contact.indices(sk.names, "feet"))) for j in chain})
    rest = [j for j in range(sk.num_joints) if j not in leg]
    assert np.array_equal(q1[:31, rest], q0[:31, rest]) and not np.array_equal(q1[:31, leg], q0[:31, leg])
