"""Distillation (src/inbetweening/training/distil.py, ``teacher=``, ``experiment=distil``): the teacher's target is what
the fill gives for the task, in the student's own frame and features, and a run with a teacher trains and records it."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra

from conftest import CONF_DIR, TINY_CKPT_OVERRIDES, compose_cfg
from inbetweening.runtime import FillRuntime
from inbetweening.runtime.torch_backend import TorchBackend
from inbetweening.training.config import ConfigError
from inbetweening.training.distil import Teacher


def _motion(skeleton, frames: int, seed: int = 0):
    """A smooth motion of ``skeleton`` written with the test's own lines: the root walking, joints swinging."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None]
    root = np.concatenate([40 * np.sin(t / 17), 90 + 2 * np.sin(t / 4), 2.5 * t], -1)
    j = skeleton.num_joints
    ang = 0.3 * np.sin(t[:, :, None] / rng.uniform(5, 12, (1, j, 3)) + rng.uniform(0, 6, (1, j, 3)))
    q = np.concatenate([np.ones((frames, j, 1)), ang], -1)
    return root, q / np.linalg.norm(q, axis=-1, keepdims=True)


def test_the_teacher_predicts_the_task_as_the_fill_does(tiny_checkpoint):
    """Context, a transition, its target key, known frames after: the teacher's frames are the fill's (keys before the
    gap and its target key, no blend, no self-check, no feet), the other frames the window's own."""
    teacher = Teacher([str(tiny_checkpoint)])
    sk, p = teacher.info.skeleton, teacher.info.n_past
    root, q = _motion(sk, 40)
    n = 12
    known = np.ones((2, 40, sk.num_joints), dtype=bool)
    known[:, p : p + n] = False
    known[1] = True  # the second window's transition starts later: context 15 frames
    known[1, 15 : 15 + n] = False
    roots, qs = np.stack([root, np.roll(root, 3, axis=0)]), np.stack([q, np.roll(q, 3, axis=0)])
    t_root, t_q = teacher.targets(torch.from_numpy(roots), torch.from_numpy(qs), torch.from_numpy(known),
                                  torch.tensor([n, n]), torch.tensor([p, 15]))
    backend = TorchBackend.from_checkpoint(tiny_checkpoint)
    backend.info = replace(backend.info, blend=None)  # the network alone, as the teacher gives it
    fill = FillRuntime(backend, self_check=False, foot_lock=False)
    for i, start in enumerate((p, 15)):
        keys = list(range(start)) + [start + n]
        out = fill.fill(roots[i], qs[i], keys)
        np.testing.assert_allclose(t_root[i, start : start + n].numpy(), out.root[start : start + n], atol=1e-5)
        dots = np.abs(np.sum(t_q[i, start : start + n].numpy() * out.local_q[start : start + n], -1))
        assert dots.min() > 1 - 1e-6
        outside = np.r_[0:start, start + n : 40]
        np.testing.assert_array_equal(t_root[i, outside].numpy(), roots[i, outside])


def test_keys_inside_the_transition_are_the_teachers_too(tiny_checkpoint):
    """An intermediate key on the transition's first frame and a partial key later (``data.keyframes_max``,
    ``data.partial_prob``): the transition still starts after the context, the teacher sees those keys as the fill
    would (the same prediction as the fill given them), and nothing outside the transition changes."""
    teacher = Teacher([str(tiny_checkpoint)])
    sk, p = teacher.info.skeleton, teacher.info.n_past
    n, frames = 10, p + 10 + 1
    root, q = _motion(sk, frames, seed=5)
    known = np.zeros((1, frames, sk.num_joints), dtype=bool)
    known[:, :p] = known[:, p + n] = True
    known[:, p] = True  # a whole key on the transition's first frame
    known[:, p + 4, :3] = True  # a partial key: three joints
    r, qq = torch.from_numpy(root[None]), torch.from_numpy(q[None])
    t_root, t_q = teacher.targets(r, qq, torch.from_numpy(known), torch.tensor([n]), torch.tensor([p]))
    pr, pq, _ = teacher.runtime.predict_windows(root[None], q[None], known)
    np.testing.assert_allclose(t_root[0, p : p + n].numpy(), pr[0], atol=1e-9)
    outside = np.r_[0:p, p + n : frames]
    np.testing.assert_array_equal(t_root[0, outside].numpy(), root[outside])
    np.testing.assert_array_equal(t_q[0, outside].numpy(), q[outside])


def test_a_student_that_is_its_teacher_has_nothing_to_learn(tiny_checkpoint):
    """The teacher's target in the student's features: a student with the teacher's weights and statistics, given the
    window the fill gives (context, transition, target key), predicts its rotations and root (the other joints'
    positions of the target are the teacher's motion's, by FK, as the data's are), while it does not predict the data:
    the two targets are in one frame and scale."""
    from inbetweening.predictor.checkpoint import load_predictor
    student = load_predictor(str(tiny_checkpoint), "cpu").eval()
    student.blend = None
    teacher = Teacher([str(tiny_checkpoint)])
    p, n = student.n_past, 14
    root, q = _motion(student.skeleton, p + n + 1, seed=3)
    known = np.ones((1, p + n + 1, student.skeleton.num_joints), dtype=bool)
    known[:, p : p + n] = False
    known_t = torch.from_numpy(known)
    r, qq = torch.from_numpy(root[None]), torch.from_numpy(q[None])
    with torch.no_grad():
        pred, _, gt = student(r, qq, known_t)
        t_root, t_q = teacher.targets(r, qq, known_t, torch.tensor([n]), torch.tensor([p]))
        target, _ = student.canonical_features(t_root, t_q, known_t)
    mask = ~known_t
    rep = student.representation
    quat, root_pos = (slice(None), slice(None), slice(None), rep.quat), (slice(None), slice(None), 0, rep.pos)
    # what the teacher's motion holds, the rotations and the root, is the student's prediction ...
    torch.testing.assert_close(pred[quat][mask], target[quat][mask], atol=1e-4, rtol=0)
    torch.testing.assert_close(pred[root_pos][mask[..., 0]], target[root_pos][mask[..., 0]], atol=1e-4, rtol=0)
    # ... while the data's motion is not
    assert (pred[quat][mask] - gt[quat][mask]).abs().mean() > 1e-2


def test_teacher_config_errors_name_the_key(tiny_checkpoint, tmp_path):
    from inbetweening.training.config import validate

    for overrides, says in [(["teacher.checkpoints=[nope.ckpt]"], "teacher.checkpoints: no checkpoint file nope.ckpt"),
                            ([f"teacher.checkpoints=['{tiny_checkpoint}']", "teacher.weight=0"], "teacher.weight")]:
        GlobalHydra.instance().clear()
        with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
            cfg = compose("train", overrides=["teacher=shipped", *overrides])
        with pytest.raises(ConfigError, match=says):
            validate(cfg)
    with pytest.raises(ConfigError, match="another skeleton"):
        from inbetweening.geometry.skeleton import Skeleton

        Teacher([str(tiny_checkpoint)]).check(Skeleton(["a", "b"], [-1, 0], np.zeros((2, 3))), 30.0)


def test_the_teacher_takes_data_at_its_rate_as_a_file_gives_it(tiny_checkpoint):
    """A folder of the teacher's own takes reads 30 fps where the teacher's data read 30.00003 (a frame time written
    as 0.033333): the same rate; 24 fps is not."""
    teacher = Teacher([str(tiny_checkpoint)])
    fps, sk = teacher.info.fps, teacher.info.skeleton
    teacher.check(sk, fps + 3e-5)
    teacher.check(sk, 1.0 / round(1.0 / fps, 6))
    with pytest.raises(ConfigError, match=r"teacher.checkpoints: .* fps, the data is at 24"):
        teacher.check(sk, 24.0)


@pytest.mark.slow
def test_a_run_with_a_teacher_trains_and_records_it(tiny_checkpoint, tmp_path, cache_dir):
    """``teacher=shipped teacher.checkpoints=[...]`` on the tiny run: it trains, the teacher moves its weights (the same
    run without it ends elsewhere), its checkpoint names the teacher, and the student loads for the fill without it."""
    from inbetweening.predictor.checkpoint import load_predictor, read_checkpoint
    from inbetweening.training.train import train

    GlobalHydra.instance().clear()
    cfg = compose_cfg("train", [*TINY_CKPT_OVERRIDES, "teacher=shipped", f"teacher.checkpoints=['{tiny_checkpoint}']",
                                "teacher.weight=0.5"], tmp_path, cache_dir)
    train(cfg)
    ckpt = sorted((tmp_path / "checkpoints").glob("*.ckpt"))[-1]
    hp = read_checkpoint(str(ckpt))["hyper_parameters"]
    assert hp["teacher"] == {"checkpoints": [str(tiny_checkpoint)], "weight": 0.5}
    student = load_predictor(str(ckpt), "cpu")
    GlobalHydra.instance().clear()
    train(compose_cfg("train", TINY_CKPT_OVERRIDES, tmp_path / "alone", cache_dir))
    alone = load_predictor(str(sorted((tmp_path / "alone" / "checkpoints").glob("*.ckpt"))[-1]), "cpu")
    diff = [float((a - b).abs().max()) for a, b in zip(student.net.parameters(), alone.net.parameters())]
    assert max(diff) > 1e-6
