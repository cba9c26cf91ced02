"""The ensemble backend (runtime/ensemble.py): the members' weighted mean as one network, through the fill runtime,
the API and the CLI."""
from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from inbetweening import Inbetweener
from inbetweening.cli import predict
from inbetweening.data.bvh import read_bvh
from inbetweening.data.bvh_writer import write_bvh
from inbetweening.data.synthetic import generate_clip, make_bvh
from inbetweening.runtime import FillRuntime, ModelError
from inbetweening.runtime.ensemble import EnsembleBackend, ensemble_info, member_weights
from inbetweening.runtime.torch_backend import TorchBackend


@pytest.fixture(scope="module")
def pair(tiny_checkpoint, tiny_contact_checkpoint):
    return TorchBackend.from_checkpoint(tiny_checkpoint), TorchBackend.from_checkpoint(tiny_contact_checkpoint)


def _windows(backend, b=3, gap=6, seed=0):
    rng = np.random.default_rng(seed)
    info = backend.info
    t = info.n_past + gap + 1
    root = rng.normal(size=(b, t, 3)) * 5
    q = rng.normal(size=(b, t, info.skeleton.num_joints, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    known = np.zeros((b, t, info.skeleton.num_joints), dtype=bool)
    known[:, : info.n_past] = known[:, -1] = True
    return root, q, known


def test_an_ensemble_of_a_model_with_itself_is_the_model(pair):
    a, _ = pair
    ens = EnsembleBackend([a, a])
    root, q, known = _windows(a)
    ra, qa, _ = a.predict(root, q, known, None)
    re, qe, _ = ens.predict(root, q, known, None)
    assert np.allclose(re, ra, atol=1e-9) and np.allclose(qe, qa, atol=1e-9)
    assert ens.info.blend == a.info.blend and ens.info.trained_gap == a.info.trained_gap


def test_members_are_weighted_by_their_calibrated_weight_for_the_gap(pair):
    a, b = (copy.copy(m) for m in pair)  # copies whose blend tables we set
    a.info = dataclasses.replace(a.info, blend=(0.9, 0.8, 0.6))
    b.info = dataclasses.replace(b.info, blend=(0.1, 0.2, 0.2))
    ens = EnsembleBackend([a, b])
    assert ens.share_power == 4
    assert np.allclose(member_weights([a.info, b.info], 1), [0.6561 / 0.6562, 0.0001 / 0.6562])  # weights ** 4
    sa, sb = 0.1296 / 0.1312, 0.0016 / 0.1312  # longer gaps: the tables' last weights, 0.6 and 0.2, ** 4
    assert np.allclose(member_weights([a.info, b.info], 7), [sa, sb])
    assert ens.info.blend == (0.9, 0.8, 0.6)  # the most trusted member's weight per gap length
    assert ens.info.has_contacts  # a member predicts contact
    root, q, known = _windows(a, gap=3)
    (ra, qa, ca), (rb, qb, cb) = a.predict(root, q, known, None), b.predict(root, q, known, None)
    re, qe, ce = ens.predict(root, q, known, None)
    assert np.allclose(re, sa * ra + sb * rb)
    assert ca is None and np.allclose(ce, cb)
    qb_aligned = np.where(np.sum(qa * qb, -1, keepdims=True) < 0, -qb, qb)
    mean = sa * qa + sb * qb_aligned
    assert np.allclose(qe, mean / np.linalg.norm(mean, axis=-1, keepdims=True))
    assert np.allclose(np.linalg.norm(qe, axis=-1), 1.0)
    assert not np.allclose(re, ra)  # the two networks differ: the test sees the mean


class _Counted:
    """A member that counts the windows it is asked to predict."""

    def __init__(self, member):
        self.member, self.info, self.windows = member, member.info, 0

    def predict(self, root, *args, **kw):
        self.windows += len(root)
        return self.member.predict(root, *args, **kw)


def test_a_member_with_no_share_runs_only_for_the_contact_it_gives(pair, tiny_checkpoint):
    plain, contact = (copy.copy(m) for m in pair)
    plain.info = dataclasses.replace(plain.info, blend=(0.9, 0.8, 0.6))
    contact.info = dataclasses.replace(contact.info, blend=(0.0, 0.0, 0.0, 0.5))  # no share in gaps of 1-3 frames
    idle = copy.copy(pair[0])
    idle.info = dataclasses.replace(idle.info, blend=(0.0, 0.0, 0.0, 0.5))  # no share there, no contact either
    members = [_Counted(m) for m in (plain, contact, idle)]
    ens = EnsembleBackend(members)
    root, q, known = _windows(plain, b=2, gap=3)
    ra, qa, _ = plain.predict(root, q, known, None)
    _, _, cb = contact.predict(root, q, known, None)
    r, qe, c = ens.predict(root, q, known, None)  # the contact wanted: the contact member runs, the idle one not
    assert np.array_equal(r, ra) and np.allclose(qe, qa / np.linalg.norm(qa, axis=-1, keepdims=True), atol=1e-12)
    assert np.allclose(c, cb) and [m.windows for m in members] == [2, 2, 0]
    r2, q2, c2 = ens.predict(root, q, known, None, contacts=False)  # the self-check's windows: only the one with a share
    assert np.array_equal(r2, r) and np.array_equal(q2, qe) and c2 is None
    assert [m.windows for m in members] == [4, 2, 0]
    root, q, known = _windows(plain, b=2, gap=5)  # every member has a share at 5 frames: all run
    ens.predict(root, q, known, None, contacts=False)
    assert [m.windows for m in members] == [6, 4, 2]
    # through the runtime: keys 10, 12, 14, 16 are checked, 12 and 14 across 3-frame gaps where the first member alone
    # has a share; the fill generates gaps of 9, 1, 1, 1 and 13 frames
    local_q, root_pos = generate_clip(np.random.default_rng(5), 40)
    keys = [0, 10, 12, 14, 16, 30]
    runtime = FillRuntime(ens)
    before = [m.windows for m in members]
    out = runtime.fill(root_pos, local_q, keys)
    assert len(out.checks) == 4 and np.array_equal(out.root[keys], root_pos[keys])
    ran = [m.windows - b for m, b in zip(members, before)]
    assert ran[0] - ran[1] == 2  # the two 3-frame checks: not the contact member (the check reads no contact)
    assert ran[1] - ran[2] == 3  # the three 1-frame gaps generated: the contact member for its contact, not the idle one


def test_a_member_of_another_skeleton_is_refused_by_name(pair):
    a, b = pair
    other = dataclasses.replace(b.info, n_past=b.info.n_past + 1)
    with pytest.raises(ModelError, match="second.ckpt has another n_past than first.ckpt"):
        ensemble_info([a.info, other], ["first.ckpt", "second.ckpt"])
    skel = a.info.skeleton
    moved = dataclasses.replace(a.info, skeleton=type(skel)(skel.names, skel.parents, skel.offsets * 2))
    with pytest.raises(ModelError, match="another skeleton"):
        ensemble_info([a.info, moved])
    with pytest.raises(ModelError, match="no models"):
        ensemble_info([])


def test_the_ensemble_fills_with_keys_exact_through_the_runtime_the_api_and_the_cli(tiny_checkpoint,
                                                                                    tiny_contact_checkpoint, tmp_path,
                                                                                    monkeypatch, capsys):
    paths = [str(tiny_checkpoint), str(tiny_contact_checkpoint)]
    ib = Inbetweener.from_checkpoint(paths)
    assert isinstance(ib.backend, EnsembleBackend)
    local_q, root = generate_clip(np.random.default_rng(3), 80)
    bvh_path = tmp_path / "clip.bvh"
    write_bvh(make_bvh(local_q, root), bvh_path)
    clip = read_bvh(bvh_path)
    keys = [0, 20, 50, 79]
    out = ib.fill(clip, keyframes=keys)
    assert np.array_equal(out.motion[keys], clip.motion[keys])
    singles = [Inbetweener.from_checkpoint(p).fill(clip, keyframes=keys).motion for p in paths]
    assert not np.allclose(out.motion, singles[0]) and not np.allclose(out.motion, singles[1])
    runtime = FillRuntime(EnsembleBackend([TorchBackend.from_checkpoint(p) for p in paths]))
    assert runtime.info.has_contacts and ib.runtime.info.blend == runtime.info.blend
    monkeypatch.chdir(tmp_path)
    assert predict.run([f"ckpt_path=[{paths[0]},{paths[1]}]", "input=clip.bvh", "keyframes=0,20,50,79",
                        "output=o.bvh"]) == 0
    assert np.allclose(read_bvh(tmp_path / "o.bvh").motion, out.motion, atol=1e-4)
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        predict.run([f"ckpt_path=[{paths[0]},absent.ckpt]", "input=clip.bvh", "keyframes=0,20", "output=p.bvh"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and len(err.strip().splitlines()) == 1 and "absent.ckpt" in err
    with pytest.raises(SystemExit) as exc:
        predict.run([f"ckpt_path=[{paths[0]},clip.bvh]", "input=clip.bvh", "keyframes=0,20", "output=clip.bvh"])
    assert exc.value.code == 2 and "is the input file" in capsys.readouterr().err
