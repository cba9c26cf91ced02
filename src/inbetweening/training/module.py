"""The LightningModule: builds any model of the zoo from plain config values, trains it with the
method's L1 loss (plus optional terms), validates/tests with the benchmark metrics.

Everything in ``hparams`` is a plain value (dicts, lists, numbers, strings), so
``InbetweenModule.load_from_checkpoint(path)`` rebuilds the network without Hydra.
"""
from __future__ import annotations

import io
from collections.abc import Iterable, Mapping, Sequence
from fnmatch import fnmatchcase
from pathlib import Path

import lightning as L
import numpy as np
import torch

from inbetweening.evaluation.metrics import BenchmarkMetric, PerJointError
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.predictor.checkpoint import (
    CheckpointError,
    peek_hyper_parameters,
    read_checkpoint,
    read_checkpoint_bytes,
    upgrade_module_state,
)
from inbetweening.predictor.masks import JointGaps
from inbetweening.predictor.predictor import LEGACY_CENTRE, Predictor
from inbetweening.predictor.settings import PredictorSettings
from inbetweening.training.adapters import LowRankAdapters
from inbetweening.training.config import ConfigError
from inbetweening.training.distil import Teacher
from inbetweening.training.losses import total_loss
from inbetweening.training.schedules import build_optimizers, upgrade_optim
from inbetweening.training.tb_logging import tb_scalars

_DEFAULT = PredictorSettings.defaults()  # the predictor's settings take the defaults they persist with


class InbetweenModule(L.LightningModule):
    """In-betweening training/evaluation around a :class:`~inbetweening.predictor.predictor.Predictor` (which
    holds the network of :mod:`inbetweening.models`); every path from windows to predictions goes through it.

    Args:
        model: model config (``name`` + constructor kwargs; ``hops`` builds a k-hop relation matrix).
        skeleton: ``Skeleton.to_dict()`` of the training data.
        pos_mean, pos_std: training statistics of global positions, ``J*3`` floats each.
        mask: ``zero`` | ``lerp`` | ``joints`` (what the network sees in place of unknown values), or the ``mask``
            config group (``name`` + the gap settings of ``joints``), recorded as ``mask`` and ``joint_mask``.
        loss: weights of the loss terms (see :mod:`inbetweening.training.losses`).
        optim: ``optimizer`` and ``scheduler`` partials (``_target_`` dicts, see :mod:`inbetweening.training.schedules`;
            the old form ``name`` adam|adamw|sgd, ``lr``, ``warmup_steps``, ... is upgraded).
        val_lengths, test_lengths: transition lengths scored by the benchmark metrics.
        dataset: name of the training dataset (recorded in ``benchmark.json``).
        forward_axis, fps, train_window: data conventions, kept so tools can prepare new windows alike.
        joint_mask: gap settings of the mocap-recovery task (``mask=joints``): ``gap_min``, ``gap_max``,
            ``frac_min``, ``frac_max``; validation/test then also score recovery of missing joints.
        centre: required, no default.  ``known`` re-centres each window on the mean root XZ of its known frames
            before the network (no information about the frames to predict leaks through the window's centring);
            ``window`` feeds the benchmark's window-centred data as is.  Checkpoints made before the option load
            with ``window`` (what they did).
        representation: the feature representation's name (:mod:`inbetweening.representation`).
        contact, convention: the training data's feet and contact rule, and its files' up axis and unit (kept by the
            predictor for the tools; the foot loss uses the feet and the contact speed).
        blend: the predictor's do-no-harm blend (one weight per gap length; written by the calibration after training,
            :func:`inbetweening.predictor.calibration.fit_blend`); ``None``: the network as it is.
        score_stats: ``{"mean": [...], "std": [...]}``, the statistics the benchmark metrics z-score L2P with
            (``eval.py``: the scored dataset's own training statistics, the protocol's); ``None``: the model's.
        teacher: distillation (the ``teacher`` group): ``{"checkpoints": [...], "weight": w}``, the networks whose
            prediction of each training task the loss also follows (:class:`~inbetweening.training.distil.Teacher`,
            loaded when fitting starts); ``None``: the data alone.
    """

    def __init__(
        self,
        model: dict,
        skeleton: dict,
        pos_mean: Sequence[float],
        pos_std: Sequence[float],
        mask: str | Mapping = _DEFAULT["mask"],
        loss: dict | None = None,
        optim: dict | None = None,
        val_lengths: Sequence[int] = (5, 15, 30),
        test_lengths: Sequence[int] = (5, 15, 30, 45),
        dataset: str = _DEFAULT["dataset"],
        n_past: int = _DEFAULT["n_past"],
        forward_axis: Sequence[float] = _DEFAULT["forward_axis"],
        fps: float = _DEFAULT["fps"],
        train_window: int = _DEFAULT["train_window"],
        joint_mask: dict | None = None,
        *,
        centre: str,
        representation: str = _DEFAULT["representation"],
        score_stats: dict | None = None,
        contact: dict | None = None,
        convention: dict | None = None,
        blend: Sequence[float] | None = None,
        teacher: dict | None = None,
    ):
        super().__init__()
        if isinstance(mask, Mapping):  # the ``mask`` config group: its name, and the gap settings of mask=joints
            mask, joint_mask = str(mask["name"]), (dict(mask) if mask["name"] == "joints" else None)
        self.save_hyperparameters(ignore=["score_stats"])  # (records the name and the gap settings, as always)
        self.predictor = Predictor.from_hparams(dict(self.hparams))
        self.loss_weights = dict(loss or {"l1": 1.0})
        self.optim_cfg = upgrade_optim(optim)  # checkpoints of the old form (optim.name, optim.lr, ...) still load
        self.hparams["optim"] = self.optim_cfg
        self.frozen = freeze(self.net, self.optim_cfg.get("freeze") or ())  # optim.freeze: kept as they are
        # optim.adapters: low-rank changes of the linear layers trained instead of the network's weights
        self.adapters = LowRankAdapters.of(self.net, self.optim_cfg.get("adapters"))
        j = self.skeleton.num_joints
        mean, std = (self.mean, self.std) if score_stats is None else (score_stats["mean"], score_stats["std"])
        self.val_bench = BenchmarkMetric(mean, std, val_lengths)
        self.test_bench = BenchmarkMetric(mean, std, test_lengths)
        self.val_joint = PerJointError(j)
        self.test_joint = PerJointError(j)
        # TensorBoard references: interpolation scored on the same windows (validation: once per fit, cached),
        # and per-joint errors per transition length for the per-joint figure
        self.val_interp = BenchmarkMetric(mean, std, val_lengths)
        self.test_interp = BenchmarkMetric(mean, std, test_lengths)
        self.val_joint_len = torch.nn.ModuleDict({f"{k}{n}": PerJointError(j) for n in val_lengths for k in "mi"})
        self.test_joint_len = torch.nn.ModuleDict({f"{k}{n}": PerJointError(j) for n in test_lengths for k in "mi"})
        self.val_interp_cache: dict | None = None  # (interp metrics, interp per-joint) of this fit's validation set
        self.val_l2p_mean_best: float | None = None
        self.val_improved = False
        self.joint_errors: dict[str, dict] = {}
        self.test_interp_results: dict[str, float] = {}
        self.stage_logs: dict[str, dict[str, float]] = {}  # the scalars last logged per stage (test: for train.py)
        self.test_results: dict[str, float] = {}
        self.joint_gaps = JointGaps.from_config(joint_mask)
        self.val_recovery = PerJointError(j)
        self.test_recovery = PerJointError(j)
        self._train_forward = None  # compile_network(): the network's compiled forward, for training steps only
        self.teacher_cfg, self.teacher = (dict(teacher) if teacher else None), None

    def compile_network(self, on: bool = True) -> None:
        """Training steps run the network's forward through ``torch.compile`` (``on``) or eagerly.  The compiled
        function is not a module, so the state dict and its keys are unchanged; validation, test and prediction
        stay eager.  Compilation happens at the first training step (and again for a new input shape)."""
        self._train_forward = torch.compile(self.predictor.net.forward) if on else None

    # ------------------------------------------------------------------ checkpoints
    @classmethod
    def load_from_checkpoint(cls, checkpoint_path, *args, **kwargs):
        """Lightning's loader; a checkpoint made before the ``centre`` option loads with ``centre="window"``."""
        if "centre" not in kwargs and "centre" not in peek_hyper_parameters(checkpoint_path):
            kwargs["centre"] = LEGACY_CENTRE
        return super().load_from_checkpoint(checkpoint_path, *args, **kwargs)

    def on_load_checkpoint(self, checkpoint: dict) -> None:
        """Older state dicts (``net.*``) are renamed to today's layout (``predictor.net.*``)."""
        checkpoint["state_dict"] = upgrade_module_state(checkpoint["state_dict"])
        self.val_l2p_mean_best = checkpoint.get("val_l2p_mean_best")

    def on_save_checkpoint(self, checkpoint: dict) -> None:
        checkpoint["val_l2p_mean_best"] = self.val_l2p_mean_best  # the best so far survives a resume

    def on_train_batch_start(self, batch, batch_idx: int) -> None:
        if self.adapters is not None:
            self.adapters.start()  # the weights the adapters change: those the first step finds (init_from's)

    def on_train_batch_end(self, outputs, batch, batch_idx: int) -> None:
        if self.adapters is not None:
            self.adapters.merge()  # the network holds its merged weights after every step

    def on_fit_start(self) -> None:
        self.val_interp_cache = None  # the validation windows may differ from a previous fit's
        if self.teacher_cfg and self.teacher is None:
            self.teacher = Teacher(**self.teacher_cfg, device=self.device)
            self.teacher.check(self.skeleton, self.predictor.fps)

    # ------------------------------------------------------------------ the predictor's settings
    @property
    def net(self) -> torch.nn.Module:
        return self.predictor.net

    @property
    def skeleton(self) -> Skeleton:
        return self.predictor.skeleton

    @property
    def mean(self) -> np.ndarray:
        return self.predictor.mean

    @property
    def std(self) -> np.ndarray:
        return self.predictor.std

    @property
    def mask_name(self) -> str:
        return self.predictor.mask_name

    @property
    def centre(self) -> str:
        return self.predictor.centre

    @property
    def n_past(self) -> int:
        return self.predictor.n_past

    @property
    def forward_axis(self) -> tuple[float, ...]:
        return self.predictor.forward_axis

    def _attached_trainer(self) -> L.Trainer | None:
        """The trainer running this module, ``None`` outside a fit or test (where Lightning's ``trainer`` raises)."""
        try:
            return self.trainer
        except RuntimeError:
            return None

    @property
    def _distributed(self) -> bool:
        trainer = self._attached_trainer()
        return trainer is not None and trainer.world_size > 1

    @property
    def trainable(self) -> bool:
        learns = any(p.requires_grad for p in self.net.parameters()) or self.adapters is not None
        return bool(getattr(self.net, "trainable", True)) and learns

    # ------------------------------------------------------------------ forward
    def forward(self, x: torch.Tensor, known: torch.Tensor, interp: torch.Tensor | None = None) -> torch.Tensor:
        """``(B, T, J, F) masked features, (B, T, J) bool, interp -> (B, T, J, F)``."""
        return self.net(x, known, interp)

    def _step_loss(self, batch: dict, stage: str) -> torch.Tensor:
        """Training batches hold windows (``root``, ``q``), their ``known`` mask and ``loss_mask``; the predictor
        canonicalises and encodes them (its one centring stage)."""
        net = self._train_forward if stage == "train" else None
        raw = None
        if self.loss_weights.get("keyframe"):  # the network's own output at the keyframes, before they are copied back
            pred, _, gt, raw = self.predictor(batch["root"], batch["q"], batch["known"], net=net, with_raw=True)
        else:
            pred, _, gt = self.predictor(batch["root"], batch["q"], batch["known"], net=net)
        pr = self.predictor
        loss, terms = total_loss(pred, gt, batch["loss_mask"], self.loss_weights, pr.representation, raw=raw,
                                 known=batch["known"], feet=pr.contact.indices(pr.skeleton.names, "contact.feet"),
                                 foot_speed=pr.contact.speed / pr.fps)
        if stage == "train" and self.teacher is not None:  # distillation: the teacher's prediction of the same task
            t_root, t_q = self.teacher.targets(batch["root"], batch["q"], batch["known"], batch["n_trans"],
                                                batch["n_context"])
            with torch.no_grad():
                target, _ = pr.canonical_features(t_root, t_q, batch["known"])
            reduce = self.loss_weights.get("reduce", "frames")
            distil = total_loss(pred, target, batch["loss_mask"], {"l1": 1.0, "reduce": reduce}, pr.representation)[0]
            terms = {**terms, "data": loss, "distil": distil}
            loss = loss + self.teacher.weight * distil
        bs = gt.shape[0]
        self.log(f"{stage}/loss", loss, prog_bar=True, batch_size=bs)
        if len(terms) > 1:  # the loss's terms, where it has several (one term is the loss itself)
            for k, v in terms.items():
                self.log(f"{stage}/loss_{k}", v, batch_size=bs)
        return loss

    def training_step(self, batch: dict, batch_idx: int) -> torch.Tensor:
        loss = self._step_loss(batch, "train")
        if "n_trans" in batch:  # the sampled transition length (frames), not a metric
            self.log("train/sampled_transition_frames", batch["n_trans"].float().mean(), batch_size=batch["q"].shape[0])
        return loss

    # ------------------------------------------------------------------ benchmark windows
    def _bench_step(self, batch: dict, stage: str) -> None:
        """Score the benchmark windows of a batch at each transition length (same path as eval.py), and the
        interpolation the predictor returns alongside (validation: the first epoch of a fit only, then cached).
        Lengths longer than the windows allow are skipped."""
        bench, joint = getattr(self, f"{stage}_bench"), getattr(self, f"{stage}_joint")
        interp_bench, per_len = getattr(self, f"{stage}_interp"), getattr(self, f"{stage}_joint_len")
        with_interp = stage == "test" or self.val_interp_cache is None
        root, q = batch["root"], batch["q"]  # (B, W, 3), (B, W, J, 4) float64, normalised windows
        pr, sk, losses = self.predictor, self.skeleton, []
        for n in bench.lengths:
            t = self.n_past + n + 1
            if t > root.shape[1]:
                continue
            known = pr.transition_known(root.shape[0], t, n, device=root.device)
            out = pr.predict_windows(root[:, :t], q[:, :t], known)
            unknown = ~known
            losses.append(total_loss(out.pred, out.feats, unknown, {"l1": 1.0}, pr.representation)[0])
            sl = slice(self.n_past, self.n_past + n)
            gt_gq, gt_gp = sk.pose(root[:, :t], q[:, :t])  # FK once per window; the metrics take global poses
            outputs = [((out.root, out.local_q), bench, joint, per_len[f"m{n}"] if f"m{n}" in per_len else None)]
            if with_interp:
                outputs.append(((out.interp_root, out.interp_q), interp_bench, None,
                                per_len[f"i{n}"] if f"i{n}" in per_len else None))
            for (pr_root, pr_q), metric, pooled, by_len in outputs:
                pr_gq, pr_gp = sk.pose(pr_root, pr_q)
                metric.update(n, pr_gq[:, sl], pr_gp[:, sl], gt_gq[:, sl], gt_gp[:, sl])
                for m in (pooled, by_len):
                    if m is not None:
                        m.update(pr_gp, gt_gp, pr_gq, gt_gq, unknown)
        if losses:
            self.log(f"{stage}/loss", torch.stack(losses).mean(), prog_bar=True, batch_size=root.shape[0],
                     sync_dist=self._distributed)

    def _recovery_step(self, batch: dict, batch_idx: int, metric: PerJointError) -> None:
        """Mocap recovery: random joints missing over random gaps of the whole window (seeded per batch)."""
        root, q = batch["root"], batch["q"]
        b, t = root.shape[:2]
        gen = torch.Generator().manual_seed(1000 + batch_idx)
        known = self.joint_gaps.known(b, t, self.skeleton.num_joints, generator=gen, device=root.device)
        out = self.predictor.predict_windows(root, q, known)
        pr_gq, _ = self.skeleton.pose(out.root, out.local_q)
        gt_gq, gt_gp = self.skeleton.pose(root, q)
        # recovered positions are the predicted global positions of the missing joints (the network's own position
        # channels, taken from the canonical frame back to the window's)
        metric.update(self.predictor.world_positions(out), gt_gp, pr_gq, gt_gq, ~known)

    def validation_step(self, batch: dict, batch_idx: int) -> None:
        self._bench_step(batch, "val")
        if self.mask_name == "joints":
            self._recovery_step(batch, batch_idx, self.val_recovery)

    def test_step(self, batch: dict, batch_idx: int) -> None:
        self._bench_step(batch, "test")
        if self.mask_name == "joints":
            self._recovery_step(batch, batch_idx, self.test_recovery)

    def _log_epoch(self, stage: str) -> dict[str, float]:
        """Compute (and reset) the stage's metrics; log the model's numbers, interpolation's on the same windows
        (``{stage}/interp_l2p@15``) and their ratios (``{stage}/l2p_ratio@15``); keep the per-joint errors per
        length for the per-joint figure.  Returns the model's benchmark metrics."""
        bench, joint, per_len = (getattr(self, f"{stage}_{k}") for k in ("bench", "joint", "joint_len"))
        res, per_joint = bench.compute(), joint.compute()
        bench.reset()
        joint.reset()
        cached = stage == "val" and self.val_interp_cache is not None
        if cached:
            interp, interp_joint = self.val_interp_cache
        else:
            interp = getattr(self, f"{stage}_interp").compute()
            getattr(self, f"{stage}_interp").reset()
            interp_joint = {}
        model_joint = {}
        for key, metric in per_len.items():
            n = int(key[1:])
            if key[0] == "m" or not cached:
                if (metric.count.sum() > 0 or self._distributed) and f"l2p@{n}" in res:
                    out = {k: v.cpu().numpy() for k, v in metric.compute().items()}
                    (model_joint if key[0] == "m" else interp_joint)[n] = out
                metric.reset()
        if stage == "val" and not cached and not self.trainer.sanity_checking and self.trainer.state.fn == "fit":
            self.val_interp_cache = (interp, interp_joint)
        self.joint_errors[stage] = {"model": model_joint, "interp": interp_joint}
        logs = tb_scalars(stage, res, interp, float(per_joint["rmse"]))
        if stage == "val" and "val/l2p_mean" in logs and not self.trainer.sanity_checking:
            self.val_improved = self.val_l2p_mean_best is None or logs["val/l2p_mean"] < self.val_l2p_mean_best
            if self.val_improved:
                self.val_l2p_mean_best = logs["val/l2p_mean"]
            logs["val/l2p_mean_best"] = self.val_l2p_mean_best
        if stage == "test":
            self.test_interp_results = dict(interp)
        self.stage_logs[stage] = logs
        self.log_dict(logs, sync_dist=self._distributed)  # values are already synced: identical on every rank
        return {k: v for k, v in res.items()}

    def _log_recovery(self, metric: PerJointError, stage: str) -> dict[str, float]:
        if self.mask_name != "joints":
            return {}
        res = metric.compute()
        metric.reset()
        logs = {f"{stage}/recovery_rmse": float(res["rmse"])}
        for i, name in enumerate(self.skeleton.names):
            logs[f"{stage}_recovery_pos/{name}"] = float(res["pos"][i])
        self.log_dict(logs, sync_dist=self._distributed)
        return {"recovery_rmse": logs[f"{stage}/recovery_rmse"]}

    def on_validation_epoch_end(self) -> None:
        self._log_epoch("val")
        self._log_recovery(self.val_recovery, "val")

    def on_test_epoch_end(self) -> None:
        self.test_results = self._log_epoch("test")
        self.test_results.update(self._log_recovery(self.test_recovery, "test"))

    # ------------------------------------------------------------------ optimisation
    def _total_steps(self) -> int:
        """Optimiser steps of the whole run, as ``Trainer.estimated_stepping_batches`` counts them, but without
        building the training loader early: that would happen before a resumed run restores the loader's
        position, and the resumed epoch would restart from its first batch."""
        t = self._attached_trainer()
        if t is None:
            return 1
        dm = t.datamodule
        per_epoch = getattr(dm, "steps_per_epoch", None)
        if per_epoch is None or t.limit_train_batches != 1.0:
            return max(int(t.estimated_stepping_batches), 1)
        steps = -(-per_epoch(t.world_size) // t.accumulate_grad_batches) * max(t.max_epochs or 1, 1)
        if t.max_epochs == -1:
            steps = t.max_steps
        elif t.max_steps != -1:
            steps = min(steps, t.max_steps)
        return max(int(steps), 1)

    def configure_optimizers(self):
        params = [p for p in self.parameters() if p.requires_grad]
        if not params:  # non-trainable baselines: a dummy optimiser keeps Lightning happy
            params = [torch.nn.Parameter(torch.zeros(1))]
        return build_optimizers(self.optim_cfg, params, self._total_steps)


def freeze(net: torch.nn.Module, patterns: Iterable[str]) -> list[str]:
    """``optim.freeze``: the parameters of ``net`` whose names (``layers.0.spatial.q_proj.weight``, ``in_weight``, ...)
    match one of the ``fnmatch`` patterns keep their values: no gradient, so no optimiser step (the fine-tune's
    "which layers" lever).  Returns their names; a pattern that matches none is a ``ConfigError`` naming the
    network's parameter groups."""
    names = [n for n, _ in net.named_parameters()]
    patterns = list(patterns)
    for pat in patterns:
        if not any(fnmatchcase(n, pat) for n in names):
            groups = sorted({".".join(n.split(".")[:2]) if n.startswith("layers.") else n.split(".")[0] for n in names})
            raise ConfigError(f"optim.freeze: {pat!r} matches no parameter of the network ({type(net).__name__}: "
                              f"{', '.join(groups[:12])}{', ...' if len(groups) > 12 else ''})")
    frozen = [n for n in names if any(fnmatchcase(n, pat) for pat in patterns)]
    for n, p in net.named_parameters():
        if n in frozen:
            p.requires_grad_(False)
    return frozen


def load_module(path: str | Path, **overrides) -> InbetweenModule:
    """The :class:`InbetweenModule` of a checkpoint, on the CPU, in eval mode (``overrides``: constructor values
    replacing the recorded ones, e.g. ``score_stats``, ``test_lengths``); a wrong file is one
    :class:`~inbetweening.predictor.checkpoint.CheckpointError`."""
    raw = read_checkpoint_bytes(path)
    read_checkpoint(path, raw)
    try:
        module = InbetweenModule.load_from_checkpoint(io.BytesIO(raw), map_location="cpu", weights_only=True,
                                                      **overrides)
    except (RuntimeError, KeyError, TypeError, ValueError) as e:
        msg = " ".join(str(e).split())
        raise CheckpointError(f"ckpt_path: {path} does not match this version's models ({msg[:300]})") from None
    return module.eval()
