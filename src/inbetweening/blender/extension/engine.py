"""The extension's in-betweening engine: numpy + ONNX Runtime, no Blender, no PyTorch.

It does what :class:`inbetweening.Inbetweener` does around the network (gap planning with pseudo-keyframes for long
gaps, context windows, the world <-> canonical frame change) and runs the model's exported per-window graph
(``inbetweening.tools.export.export_window_onnx``: features, mask, centring, network, decode) with ONNX Runtime.
Arrays are in the model's skeleton and world (Y up): ``root (F, 3)``, ``local_q (F, J, 4)`` wxyz, float64.
"""
from __future__ import annotations

import itertools
import json
import math
import os

import numpy as np

WINDOW_FORMAT = "inbetweening-window-onnx/1"
REQUIRED = ("skeleton_names", "skeleton_parents", "skeleton_offsets", "n_past", "forward_axis", "trained_gap")


class ModelError(ValueError):
    """The model file is missing, unreadable or not an exported in-betweening window graph."""


# ----------------------------------------------------------------------------------------- quaternions (wxyz)
def qmul(a, b):
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def qinv(q):
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def qrot(q, v):
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + q[..., :1] * t + np.cross(u, t)


def qnormalize(q, eps: float = 1e-8):
    return q / (np.sqrt(np.sum(q * q, axis=-1, keepdims=True)) + eps)


def continuous(q):
    """Flip signs along axis 0 so consecutive quaternions have non-negative dot products."""
    dots = np.sum(q[1:] * q[:-1], axis=-1)
    sign = np.concatenate([np.ones_like(dots[:1]), np.cumprod(np.where(dots < 0, -1.0, 1.0), axis=0)], axis=0)
    return q * sign[..., None]


def slerp(q0, q1, t, linear_eps: float = 0.01):
    """Shortest-arc slerp with a linear fallback where ``1 - |dot| < linear_eps``; normalised."""
    q0, q1 = qnormalize(q0), qnormalize(q1)
    dot = np.sum(q0 * q1, axis=-1)
    q1 = np.where((dot < 0)[..., None], -q1, q1)
    dot = np.abs(dot)
    t = np.zeros_like(dot) + t
    linear = (1.0 - dot) < linear_eps
    omega = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_omega = np.where(linear, 1.0, np.sin(omega))
    w0 = np.where(linear, 1.0 - t, np.sin((1.0 - t) * omega) / sin_omega)
    w1 = np.where(linear, t, np.sin(t * omega) / sin_omega)
    return qnormalize(w0[..., None] * q0 + w1[..., None] * q1)


def facing_rotation(root_q, forward_axis):
    """Rotation about +Y taking +X to the root's facing (``forward_axis`` rotated by ``root_q``, projected on XZ),
    unit length; a half turn / identity where degenerate."""
    fwd = np.array([1.0, 0.0, 1.0]) * qrot(root_q, np.asarray(forward_axis, dtype=np.float64))
    fwd = fwd / (np.sqrt(np.sum(fwd * fwd, axis=-1, keepdims=True)) + 1e-8)
    a = np.array([1.0, 0.0, 0.0])
    w = np.sqrt(np.sum(fwd * fwd, axis=-1)) + np.sum(a * fwd, axis=-1)
    rot = qnormalize(np.concatenate([w[..., None], np.cross(a, fwd)], axis=-1))
    degenerate = (np.sum(rot * rot, axis=-1) < 0.5)[..., None]
    half, ident = np.array([0.0, 0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0, 0.0])
    rot = np.where(degenerate, np.where(fwd[..., :1] < -0.5, half, ident), rot)
    return rot / np.sqrt(np.sum(rot * rot, axis=-1, keepdims=True))


# ----------------------------------------------------------------------------------------- the model
class Model:
    """An exported window graph and its metadata (``metadata_props``, JSON values)."""

    def __init__(self, path: str, threads: int = 1):
        if not path or not os.path.isfile(path):
            raise ModelError(f"model file not found: {path!r}")
        try:
            import onnxruntime as ort
        except ImportError as e:  # pragma: no cover - the extension bundles it
            raise ModelError(f"onnxruntime is not available: {e}") from None
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = int(threads)
        opts.inter_op_num_threads = 1
        opts.log_severity_level = 3
        try:
            self.session = ort.InferenceSession(path, opts, providers=["CPUExecutionProvider"])
            raw = self.session.get_modelmeta().custom_metadata_map
            meta = {k: json.loads(v) for k, v in raw.items()}
        except Exception as e:  # onnxruntime raises its own exception types
            raise ModelError(f"{os.path.basename(path)} is not a readable ONNX model ({str(e).splitlines()[0][:200]})") \
                from None
        if meta.get("format") != WINDOW_FORMAT or any(k not in meta for k in REQUIRED):
            raise ModelError(f"{os.path.basename(path)} is not an in-betweening window model (export one with "
                             "`python -m inbetweening.blender export ckpt_path=... output=model.onnx`)")
        self.path, self.meta = path, meta
        self.names = list(meta["skeleton_names"])
        self.parents = [int(p) for p in meta["skeleton_parents"]]
        self.offsets = np.asarray(meta["skeleton_offsets"], dtype=np.float64).reshape(-1, 3)
        self.n_past = int(meta["n_past"])
        self.forward_axis = [float(a) for a in meta["forward_axis"]]
        self.trained_gap = int(meta["trained_gap"])
        self.frame_centre = str(meta.get("frame_centre", "known"))
        self.calls = 0

    @property
    def num_joints(self) -> int:
        return len(self.names)

    def predict(self, root, local_q, known):
        """Canonical windows -> predicted ``root (B, T, 3), local_q (B, T, J, 4)``."""
        self.calls += 1
        out = self.session.run(None, {"root": np.ascontiguousarray(root, dtype=np.float64),
                                      "local_q": np.ascontiguousarray(local_q, dtype=np.float64),
                                      "known": np.ascontiguousarray(known, dtype=bool)})
        return out[0], out[1]

    def fill_windows(self, root, local_q):
        """``Predictor.fill_windows``: windows of ``n_past`` context frames, ``n`` unknown frames and the target, in
        world space -> the ``n`` predicted frames ``root (B, n, 3), local_q (B, n, J, 4)``."""
        b, t = root.shape[:2]
        p = self.n_past
        n = t - p - 1
        known_t = np.zeros(t, dtype=bool)
        known_t[:p] = True
        known_t[-1] = True
        rot = facing_rotation(local_q[:, p - 1 : p, 0, :], self.forward_axis)  # (B, 1, 4)
        if self.frame_centre == "last":
            xz = root[:, p - 1 : p][..., [0, 2]]
        else:
            xz = root[:, known_t][..., [0, 2]].mean(axis=1, keepdims=True)
        centre = np.concatenate([xz[..., :1], np.zeros_like(xz[..., :1]), xz[..., 1:]], axis=-1)  # (B, 1, 3)
        inv = qinv(rot)
        wq = local_q.copy()
        wq[..., 0, :] = qmul(inv, local_q[..., 0, :])
        wr = qrot(inv, root - centre)
        known = np.broadcast_to(known_t[None, :, None], (b, t, self.num_joints))
        pr, pq = self.predict(wr, wq, known)
        pr, pq = pr[:, p : p + n], pq[:, p : p + n].copy()
        pq /= np.linalg.norm(pq, axis=-1, keepdims=True)
        pq[..., 0, :] = qmul(rot, pq[..., 0, :])
        return qrot(rot, pr) + centre, pq


# ----------------------------------------------------------------------------------------- planning and filling
def plan(keys, limit: int):
    """Segments ``[(a, b), ...]`` to generate, left to right, and the pseudo-keyframes splitting gaps longer than
    ``limit`` into ``m = ceil((b - a) / (limit + 1))`` equal parts (as ``Inbetweener`` does)."""
    segments, pseudo = [], []
    for a, b in itertools.pairwise(keys):
        if b - a < 2:
            continue
        m = math.ceil((b - a) / (limit + 1))
        points = [a + round(i * (b - a) / m) for i in range(m + 1)]
        pseudo.append((a, b, points[1:-1]))
        segments += [(s, e) for s, e in itertools.pairwise(points) if e - s > 1]
    return segments, pseudo


def fill(model: Model, root, local_q, keys, progress=None):
    """Generate every frame strictly between consecutive ``keys`` (sorted array indices) in place order, like
    ``Inbetweener.fill_arrays``; frames before ``keys[0]`` are context (the existing animation).  Returns new
    ``root (F, 3), local_q (F, J, 4)``: keys and frames outside ``[keys[0], keys[-1]]`` equal the input exactly.
    ``progress(done, total)`` is called after each generated window."""
    root = np.array(root, dtype=np.float64)
    q = np.array(local_q, dtype=np.float64)
    keys = [int(k) for k in keys]
    exact_r, exact_q = root.copy(), q.copy()
    q[: keys[-1] + 1] = qnormalize(q[: keys[-1] + 1])
    segments, pseudo = plan(keys, model.trained_gap)
    for a, b, points in pseudo:
        if points:
            w = (np.array(points) - a) / (b - a)
            root[points] = root[a] + w[:, None] * (root[b] - root[a])
            q[points] = slerp(q[a], q[b], w[:, None])
    p = model.n_past
    for i, (a, b) in enumerate(segments):
        n = b - a - 1
        idx = np.concatenate([np.clip(np.arange(a - p + 1, a + 1), 0, None), np.full(n, a), [b]])
        pr, pq = model.fill_windows(root[idx][None], continuous(q[idx])[None])
        root[a + 1 : b] = pr[0]
        q[a + 1 : b] = continuous(np.concatenate([q[a : a + 1], pq[0]]))[1:]
        if progress is not None:
            progress(i + 1, len(segments))
    outside = np.ones(len(root), dtype=bool)
    outside[keys[0] + 1 : keys[-1]] = False
    outside[keys] = True
    root[outside], q[outside] = exact_r[outside], exact_q[outside]
    return root, q
