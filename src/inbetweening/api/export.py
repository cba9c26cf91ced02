"""Export a trained network for deployment: :func:`export_onnx` (the network alone), :func:`export_window_onnx` (the
fill runtime's window computation, what the ONNX backend and the Blender extension run), :func:`export_checkpoint`
(an inference-only checkpoint).  The command line: :mod:`inbetweening.cli.export`.

The exported graph is the network alone, ``net(x, known, interp) -> out``:

* ``x``      float32 ``(B, T, J, 7)``: per joint z-scored global position (``(p - mean) / std``) + local
  quaternion wxyz, with the unknown values already filled as the training mask did (``mask`` in the
  metadata: ``lerp`` = linear positions / slerp quaternions between the nearest known frames, ``zero`` =
  zeros; ``joints`` = ``lerp``);
* ``known``  bool ``(B, T, J)``: True for given values (``n_past`` context frames, then the gap, then the target);
* ``interp`` float32 ``(B, T, J, 7)``: the lerp/slerp interpolation (graphs that do not use it have no such input);
* ``out``    float32 ``(B, T, J, 7)``: known values copied from ``x``, the others predicted.

``B`` and ``T`` are dynamic (``T = n_past + gap + 1``, at most the network's ``max_frames``).  Windows must be
normalised like the training windows (see :mod:`inbetweening.runtime.fill`).  Everything needed to prepare
them is stored in the model's ``metadata_props``, one JSON value per key: ``skeleton_names``,
``skeleton_parents``, ``skeleton_offsets``, ``pos_mean``, ``pos_std``, ``mask``, ``forward_axis``, ``n_past``,
``fps``, ``train_window``, ``max_frames``, ``model``, ``dataset``, ``centre``, the feature layout
(``representation``, ``features_per_joint``, ``position_slice``, ``quaternion_slice``, ``features``) and
``inputs`` (the graph's input names).  The windows are first moved into their canonical frame, decided by their
known frames only (:meth:`Predictor.canonical_frame <inbetweening.predictor.predictor.Predictor.canonical_frame>`:
``centre="known"`` / ``"window"``: the known frames' mean root XZ at the origin, ``"last"``: the last context
frame's root XZ; the root's ``forward_axis`` at the last context frame turned to +X about +Y), and the prediction
taken back (as :meth:`Predictor.predict_windows <inbetweening.predictor.predictor.Predictor.predict_windows>` does).
"""
from __future__ import annotations

import json
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch


class ExportError(ValueError):
    """The export could not be done (unknown format, missing package, failed check)."""


def _predictor(model):
    """The :class:`~inbetweening.predictor.predictor.Predictor` of a predictor or a training module."""
    return getattr(model, "predictor", model)


def metadata(model, inputs: Sequence[str] = ("x", "known", "interp")) -> dict[str, str]:
    """The ``metadata_props`` entries (JSON strings) describing how to prepare inputs for the network
    (:meth:`Predictor.metadata <inbetweening.predictor.predictor.Predictor.metadata>`; the feature layout comes
    from its representation).  ``inputs``: the graph's input names (``interp`` is absent when the network does
    not read it)."""
    return _predictor(model).metadata(inputs)


def random_window(model, batch: int, gap: int, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Random masked inputs ``(x, known, interp)`` for ``batch`` windows with a ``gap``-frame transition."""
    return _predictor(model).example_inputs(batch, gap, seed)


def _run_ort(session, x, known, interp) -> np.ndarray:
    feeds = {"x": x.numpy(), "known": known.numpy(), "interp": interp.numpy()}
    names = {i.name for i in session.get_inputs()}
    (out,) = session.run(None, {k: v for k, v in feeds.items() if k in names})
    return out


def _write_onnx(module: torch.nn.Module, example: tuple, path: Path, inputs: list[str], outputs: list[str],
                opset: int, meta) -> list[str]:
    """``torch.onnx.export`` of ``module`` on ``example`` to ``path`` (atomically: an interrupted export never
    leaves half a file under the final name), batch and frame axes dynamic, with ``meta`` (``{key: JSON string}``,
    or a function of the graph's input names returning it) in ``metadata_props``.  Returns the graph's input names
    (graphs that do not use an input drop it)."""
    try:
        import onnx
    except ImportError:
        raise ExportError("format=onnx needs the onnx package: pip install 'inbetweening[export]'") from None
    from inbetweening.atomic import atomic_path

    axes = {k: {0: "batch", 1: "frames"} for k in (*inputs, *outputs)}
    with atomic_path(path) as tmp:
        with warnings.catch_warnings(), torch.no_grad():
            warnings.simplefilter("ignore")
            torch.onnx.export(module, example, str(tmp), dynamo=False, opset_version=int(opset), input_names=inputs,
                              output_names=outputs, dynamic_axes=axes)
        proto = onnx.load(str(tmp))
        graph_inputs = [i.name for i in proto.graph.input]
        proto = _folded(proto, tmp)
        for k, v in (meta(graph_inputs) if callable(meta) else meta).items():
            entry = proto.metadata_props.add()
            entry.key, entry.value = k, v
        onnx.save(proto, str(tmp))
    return graph_inputs


def _folded(proto, path: Path):
    """``proto`` (saved at ``path``) with ONNX Runtime's basic graph optimisations applied once, here: constants
    folded and redundant nodes removed, standard ONNX operators only.  A session then loads the smaller graph with
    its optimisations off (:class:`~inbetweening.runtime.onnx_backend.OnnxBackend`): a shipped window graph goes
    from 3,974 to 2,438 nodes and starts about 40 % faster, with the same outputs bit for bit (tests/test_export.py).
    Without onnxruntime the graph is kept as exported."""
    import onnx

    try:
        import onnxruntime as ort
    except ImportError:  # pragma: no cover - a base dependency
        return proto
    out = path.with_name(path.name + ".folded")
    opts = ort.SessionOptions()
    opts.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_BASIC
    opts.optimized_model_filepath = str(out)
    opts.log_severity_level = 3
    try:
        ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])
        folded = onnx.load(str(out))
    finally:
        out.unlink(missing_ok=True)
    used = {n.domain for n in folded.graph.node} | {""}
    if any(d not in ("", "ai.onnx") for d in used):  # an operator of ONNX Runtime's own: keep the portable graph
        return proto
    keep = [o for o in folded.opset_import if o.domain in used]
    del folded.opset_import[:]
    folded.opset_import.extend(keep)
    del folded.metadata_props[:]
    return folded


def export_onnx(model, path: str | Path, opset: int = 17, check: bool = True) -> dict:
    """Export the network of ``model`` (a predictor or a training module) to ONNX at ``path`` with metadata;
    optionally compare with ONNX Runtime.

    Returns ``{"path", "inputs", "max_abs_diff"}`` (``max_abs_diff`` is None without ``check``).
    """
    predictor = _predictor(model)
    path = Path(path)
    inputs = _write_onnx(predictor.net.eval().cpu(), random_window(predictor, 2, 15), path, ["x", "known", "interp"],
                         ["out"], opset, lambda names: metadata(predictor, names))
    info = {"path": str(path), "inputs": inputs, "max_abs_diff": None}
    if check:
        info["max_abs_diff"] = check_onnx(predictor, path)
    return info


def _ort_session(path: str | Path):
    """An ONNX Runtime CPU session of ``path``; :class:`ExportError` when onnxruntime is missing."""
    try:
        import onnxruntime as ort
    except ImportError:
        raise ExportError("checking the export needs onnxruntime: pip install 'inbetweening[export]'") from None
    return ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])


def check_onnx(model, path: str | Path, batch: int = 3, gap: int = 7, seed: int = 1) -> float:
    """Largest absolute difference between ONNX Runtime and PyTorch on a random window."""
    session = _ort_session(path)
    x, known, interp = random_window(model, batch, gap, seed)
    got = _run_ort(session, x, known, interp)
    with torch.no_grad():
        ref = _predictor(model).net.eval().cpu()(x, known, interp).numpy()
    if got.shape != ref.shape:
        raise ExportError(f"ONNX output shape {got.shape} differs from PyTorch's {ref.shape}")
    return float(np.abs(got - ref).max())


# what an inference copy keeps; blend_fit: the do-no-harm blend's fit table (the weights themselves are hyper-parameters)
INFERENCE_KEYS = ("state_dict", "hyper_parameters", "pytorch-lightning_version", "epoch", "global_step", "blend_fit")


def export_checkpoint(src: str | Path, dst: str | Path) -> dict:
    """Write an inference-only copy of a training checkpoint (no optimiser/scheduler/loop state).

    The state dict is the predictor's own (``net.*``: what ``load_predictor`` reads; metric states dropped); the
    result still loads with ``InbetweenModule.load_from_checkpoint`` and ``Inbetweener.from_checkpoint``.
    Returns ``{"path", "bytes"}``.
    """
    from inbetweening.predictor.checkpoint import predictor_state, read_checkpoint

    ckpt = read_checkpoint(str(src))
    slim = {k: ckpt[k] for k in INFERENCE_KEYS if k in ckpt}
    slim["state_dict"] = predictor_state(ckpt["state_dict"])
    from inbetweening.atomic import atomic_path

    dst = Path(dst)
    with atomic_path(dst) as tmp:
        torch.save(slim, tmp)
    return {"path": str(dst), "bytes": dst.stat().st_size}


# ---------------------------------------------------------------------------------------------------------------
# The whole per-window path as one graph (the runtime's ONNX backend: the Blender extension's model)
# ---------------------------------------------------------------------------------------------------------------
def export_window_onnx(model, path: str | Path, opset: int = 17, check: bool = True, trained_gap: int | None = None,
                       extra: dict | None = None) -> dict:
    """Export the runtime's window computation (:class:`~inbetweening.runtime.torch_backend.WindowPath`) of ``model``
    (a predictor, a training module or an ``Inbetweener``, whose ``trained_gap`` is then the default) to ONNX at
    ``path``, with :func:`~inbetweening.runtime.torch_backend.window_metadata` (and ``extra``, JSON values) in
    ``metadata_props``: what :class:`~inbetweening.runtime.onnx_backend.OnnxBackend` runs.  Inputs ``root`` float64
    ``(B, T, 3)``, ``local_q`` float64 ``(B, T, J, 4)``, ``known`` bool ``(B, T, J)`` (windows already canonicalised),
    ``weight`` float32 ``(B, T, J)`` (the do-no-harm blend's weights; only a model with a blend has it); outputs
    ``root_out``, ``local_q_out`` (float64) and, for a model with contact channels, ``contact_out`` (float32).
    Returns ``{"path", "metadata", "max_abs_diff"}`` (ONNX Runtime vs PyTorch, or None)."""
    from inbetweening.runtime.torch_backend import WindowPath, window_metadata

    trained_gap = trained_gap or getattr(model, "trained_gap", None)
    predictor = _predictor(model).eval().cpu()
    path = Path(path)
    meta = window_metadata(predictor, trained_gap)
    meta.update({k: json.dumps(v) for k, v in (extra or {}).items()})
    _write_onnx(WindowPath(predictor).eval(), window_example(predictor, 2, 15), path,
                ["root", "local_q", "known", "weight"], json.loads(meta["outputs"]), opset, meta)
    info = {"path": str(path), "metadata": meta, "max_abs_diff": None}
    if check:
        info["max_abs_diff"] = check_window_onnx(predictor, path)
    return info


def window_example(model, batch: int, gap: int, seed: int = 0):
    """Random canonical-looking windows ``(root, local_q, known, weight)`` (float64, float64, bool, float32) with a
    ``gap``-frame transition after ``n_past`` context frames (weights in [0, 1] on the gap, 1 elsewhere)."""
    predictor = _predictor(model)
    g = torch.Generator().manual_seed(seed)
    j, t = predictor.skeleton.num_joints, predictor.n_past + gap + 1
    mean = torch.as_tensor(predictor.mean[:3], dtype=torch.float64)
    root = mean + 20.0 * torch.randn(batch, t, 3, generator=g, dtype=torch.float64)
    q = torch.randn(batch, t, j, 4, generator=g, dtype=torch.float64)
    known = predictor.transition_known(batch, t, gap)
    weight = torch.where(known, 1.0, torch.rand(batch, 1, 1, generator=g).expand(batch, t, j))
    return root, q / q.norm(dim=-1, keepdim=True), known, weight


def check_window_onnx(model, path: str | Path, batch: int = 3, gap: int = 7, seed: int = 1) -> float:
    """Largest absolute difference between ONNX Runtime and the window path in PyTorch (every output)."""
    from inbetweening.runtime.torch_backend import WindowPath

    session = _ort_session(path)
    root, q, known, weight = window_example(model, batch, gap, seed)
    names = {i.name for i in session.get_inputs()}
    feeds = {"root": root.numpy(), "local_q": q.numpy(), "known": known.numpy(), "weight": weight.numpy()}
    got = session.run(None, {k: v for k, v in feeds.items() if k in names})
    with torch.no_grad():
        ref = WindowPath(_predictor(model).eval().cpu())(root, q, known, weight)
    return float(max(np.abs(a - b.numpy()).max() for a, b in zip(got, ref)))
