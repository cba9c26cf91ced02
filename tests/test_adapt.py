"""Test-time adaptation on the user's keys (``fill.adapt_steps``, :mod:`inbetweening.runtime.adapt`), with the shipped
model on a generated clip: off, nothing changes; on, the keys stay bit for bit, every third checked key is held out,
the adapted network fills the clip only where it predicts the held-out keys better than the original (else the fill
is exactly the plain one), the runtime's own network is never changed, and the gradient steps lower their loss.  The
ONNX backend refuses it in one line."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from characters import wiggle
from inbetweening.runtime import FillRuntime, InbetweenError
from inbetweening.runtime.adapt import split_checks
from inbetweening.runtime.settings import FillSettings
from inbetweening.runtime.torch_backend import TorchBackend

MODEL = Path(__file__).resolve().parents[1] / "models" / "bn2_reference" / "model.ckpt"
KEYS = list(range(0, 121, 10))


@pytest.fixture(scope="module")
def backend():
    return TorchBackend.from_checkpoint(MODEL)


def clip(backend, seed=0):
    """A smooth random motion of the model's skeleton (tests/characters.py), 121 frames."""
    return wiggle(121, backend.info.skeleton.num_joints, seed)


def test_split_holds_out_every_third_check():
    assert split_checks(list(range(8))) == ([0, 2, 3, 5, 6], [1, 4, 7])
    assert split_checks([0, 1]) == ([0], [1])


def test_off_by_default_and_on_keeps_keys_and_decides_on_held_out_keys(backend):
    root, q = clip(backend)
    trusting = {"x_full": 99.0, "x_none": 100.0}  # the self-check trusts every gap: the network's share shows
    plain = FillRuntime(backend, settings=FillSettings(**trusting)).fill(root, q, KEYS)
    assert plain.adaptation is None
    state = {k: v.clone() for k, v in backend.predictor.state_dict().items()}
    kept = []
    for lr in (1e-4, 3e-2):  # a gentle and a ruinous learning rate
        rt = FillRuntime(backend, settings=FillSettings(adapt_steps=4, adapt_lr=lr, **trusting))
        out = rt.fill(root, q, KEYS)
        a = out.adaptation
        checked = [c.key for c in out.checks]
        assert sorted(a.adapted_on + a.held_out) == checked and list(a.held_out) == checked[1::3]
        assert np.array_equal(out.root[KEYS], root[KEYS]) and np.array_equal(out.local_q[KEYS], q[KEYS])
        assert a.kept == (a.after < a.before)
        if not a.kept:  # given back: exactly the plain fill
            assert np.array_equal(out.root, plain.root) and np.array_equal(out.local_q, plain.local_q)
        else:
            assert not np.array_equal(out.local_q, plain.local_q)
        assert [s[2] for s in out.segments] == [s[2] for s in plain.segments]  # the original's trust
        kept.append(a.kept)
    assert kept == [True, False]  # the gentle steps predict the held-out keys better, the ruinous ones worse
    assert all(torch.equal(v, state[k]) for k, v in backend.predictor.state_dict().items())  # never changed


def test_the_gradient_steps_lower_their_loss(backend):
    root, q = clip(backend, seed=1)
    rt = FillRuntime(backend)
    n = rt.info.n_past
    wr, wq = rt.windows([root] * 3, [q] * 3, [(10, 30), (30, 50), (50, 70)])
    known = rt.known_mask(3, 19)
    hidden = np.full(3, n + 9)
    keys = [20, 40, 60]
    wr[np.arange(3), hidden], wq[np.arange(3), hidden] = root[keys], q[keys]
    croot, cq, _ = rt.canonical_windows(wr, wq, known)

    def loss(b):
        feats = b.predictor.encode(croot, cq)
        with torch.no_grad():
            out = b.predictor.network_forward(feats, torch.as_tensor(known), blend=False)[0]
        return float((out[torch.arange(3), torch.as_tensor(hidden)] - feats[torch.arange(3), torch.as_tensor(hidden)])
                     .abs().mean())

    adapted = backend.adapted([(croot, cq, known, hidden)], steps=10, lr=1e-3)
    assert loss(adapted) < 0.8 * loss(backend)


def test_a_backend_without_gradient_steps_refuses_adaptation(backend):
    class Numpy:
        info = backend.info

        def predict(self, *a):
            raise AssertionError

    with pytest.raises(InbetweenError, match=r"^fill.adapt_steps: test-time adaptation needs the PyTorch backend"):
        FillRuntime(Numpy(), settings=FillSettings(adapt_steps=2))
