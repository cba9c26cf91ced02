"""LightningDataModule: in-betweening tasks on windows of any dataset of :mod:`inbetweening.data.datasets`.

Training windows (50 frames every 20) are cut from the clips in memory when a batch asks for them
(:class:`inbetweening.data.windows.ClipWindows`), in the clips' own frame: the predictor canonicalises each window
on its known frames.  Each training batch gets 10 context frames, a transition of random length
(``transition_min`` .. ``transition_max``, drawn per batch or per sample) and the target keyframe; frames after the
target are not part of the task.  Validation and test batches are the benchmark's 65-frame windows, normalised by the
protocol (validation: a held-out part of the training clips; test: the dataset's test split).

Batch keys (train): ``root (B, T, 3)``, ``q (B, T, J, 4)`` float64, ``known (B, T, J)`` bool, ``loss_mask (B, T, J)``
bool, ``n_trans (B,)``.  Batch keys (val/test): ``root (B, 65, 3)``, ``q (B, 65, J, 4)`` float64.
"""
from __future__ import annotations

import lightning as L
import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset

from inbetweening.data import windows as W
from inbetweening.data.bvh_folder import FolderOptions
from inbetweening.data.datasets import MotionData, load_dataset
from inbetweening.predictor.masks import JointGaps
from inbetweening.predictor.settings import PredictorSettings
from inbetweening.training.sampling import (
    EpochPermutation,
    IndexDataset,
    ResumableBatchSampler,
    ResumableLoader,
    mix_seed,
    rank_world,
)
from inbetweening.training.tasks import draw_task, mix_body_parts, partial_keys, task_window, upper_body, upper_limbs


def _plain(v):
    """A config value (OmegaConf lists included) as plain Python values."""
    if v is None or isinstance(v, (str, int, float, bool)):
        return v
    return [_plain(x) for x in v]


class _Windows(Dataset):
    def __init__(self, X: np.ndarray, Q: np.ndarray):
        self.root = torch.from_numpy(np.ascontiguousarray(X[:, :, 0]))
        self.q = torch.from_numpy(np.ascontiguousarray(Q))

    def __len__(self) -> int:
        return len(self.root)

    def __getitem__(self, i: int) -> dict:
        return {"root": self.root[i], "q": self.q[i]}


def split_train_val(clips: list, val_fraction: float) -> tuple[list, list]:
    """Deterministic hold-out: every k-th clip (sorted by name) goes to validation, ``k ~ 1 / val_fraction``;
    at least one clip whenever there are two or more (small datasets never validate on training clips)."""
    if val_fraction <= 0:
        return clips, []
    order = sorted(range(len(clips)), key=lambda i: clips[i].name)
    k = max(2, min(round(1 / val_fraction), len(clips)))
    val_idx = set(order[k - 1 :: k])
    return [c for i, c in enumerate(clips) if i not in val_idx], [c for i, c in enumerate(clips) if i in val_idx]


class InbetweenDataModule(L.LightningDataModule):
    """Built by ``hydra.utils.instantiate(cfg.data)``: ``conf/data/*.yaml`` hold exactly these arguments (the values
    live there, so none has a default here); ``mask`` and ``seed`` are the run's (``${mask}``, ``${seed}``).

    Args:
        name, path, cache_dir, forward_axis, synthetic, download, split: the dataset (see
            :func:`inbetweening.data.datasets.load_dataset`); ``split`` names one of its spec's split rules
            (``standard``; ``bandai_namco`` also has ``content``).  Validation clips come from its training part.
        up_axis, unit, fps, feet, fold_root, test_pattern, mirror_map, contact_height, contact_speed: ``data=bvh``'s
            overrides of what it derives from the files (:class:`inbetweening.data.bvh_folder.FolderOptions`;
            ``None``: derive).
        batch_size, eval_batch_size, num_workers: loaders (``eval_batch_size``: validation and test).
        val_fraction: share of the training clips held out for validation.
        transition_min, transition_max, transition_per: transition lengths drawn for training batches
            (per ``batch`` or per ``sample``).
        train_window, train_offset: training windows (frames, stride).
        context_min, context_max: context frames per training sample (``10, 10``: the benchmark's; ``1, 10``
            trains for keyframes alone too).
        keyframes_max, keyframe_prob: with probability ``keyframe_prob`` a sample gets ``1..keyframes_max`` extra
            known frames inside its transition.
        partial_prob: each of those keyframes is, with this probability, a partial key: known on one body part only
            (:func:`~inbetweening.training.tasks.partial_keys`; the animator keyed some bones).
        extra, extra_repeat: takes of other rigs added to the training clips (folders, zips or BVH files of any
            humanoid skeleton, each moved onto the dataset's skeleton by the fill's retargeter:
            :mod:`inbetweening.training.other_rigs`), each clip ``extra_repeat`` times; ``None``: none.
        mirror: mirror each training window left/right with probability 0.5 (the dataset's mirror map).
        speed: ``[lo, hi]`` play each training window at a speed drawn log-uniformly in that range (time warp: faster
            and slower versions of the training motions; slowed where the clip ends); ``None``: off.
        speed_vary: with ``speed``, draw two speeds per window, the play-back speed changing linearly from one to
            the other across it (a time warp that varies within the motion).
        mix_parts: body-part mixing (:func:`~inbetweening.training.tasks.mix_body_parts`; the legs and root, the feet
            on the ground, stay): ``true`` or ``"upper"``, half the training windows take the upper body of another
            window of the batch; ``"limbs"``, each limb of the upper body (head, each arm) is taken from its own
            donor in half the windows, so one-handed motions compose two-handed ones; ``false``: off.
        val_lengths, test_lengths: transition lengths the validation and test benchmarks score (passed on to
            the LightningModule by :meth:`model_kwargs`).
        max_train_windows, max_eval_windows, max_val_windows: caps for quick runs (``None``: all windows;
            ``max_eval_windows`` caps validation and test, ``max_val_windows`` validation only).
        mask: the ``mask`` group: ``name`` (``zero`` | ``lerp`` | ``joints``) and, for ``joints``, the gap settings
            (:class:`inbetweening.predictor.masks.JointGaps`).
        seed: seeds the window order and the per-batch draws (a pure function of seed, epoch and batch).
    """

    def __init__(
        self,
        *,
        name: str,
        path: str | None,
        cache_dir: str | None,
        forward_axis: list[float] | None,
        synthetic: dict | None,
        download: bool,
        split: str,
        up_axis: str | None,
        unit: str | float | None,
        fps: float | None,
        feet: list[str] | None,
        fold_root: bool | None,
        test_pattern: str | list[str] | None,
        mirror_map: list[list[str]] | None,
        contact_height: float | None,
        contact_speed: float | None,
        batch_size: int,
        eval_batch_size: int,
        num_workers: int,
        val_fraction: float,
        transition_min: int,
        transition_max: int,
        transition_per: str,
        train_window: int,
        train_offset: int,
        context_min: int,
        context_max: int,
        keyframes_max: int,
        keyframe_prob: float,
        partial_prob: float,
        extra: str | list[str] | None,
        extra_repeat: int,
        mirror: bool,
        speed: list[float] | None,
        speed_vary: bool,
        mix_parts: bool | str,
        val_lengths: list[int],
        test_lengths: list[int],
        max_train_windows: int | None,
        max_eval_windows: int | None,
        max_val_windows: int | None,
        mask: dict,
        seed: int,
    ):
        super().__init__()
        self.save_hyperparameters(logger=False)  # the module logs the resolved data conventions
        self.mask_name = str(mask["name"])
        self.joint_gaps = JointGaps.from_config(mask)
        self.data: MotionData | None = None
        self.clip_windows: W.ClipWindows | None = None
        self.parts = None

    # ------------------------------------------------------------------ setup
    def load_data(self) -> MotionData:
        """The dataset (read from its cache, built on first use), without setting anything up."""
        h = self.hparams
        path = h.path if h.path is None or isinstance(h.path, str) else [str(p) for p in h.path]
        folder = FolderOptions(h.up_axis, h.unit, None, h.fps, _plain(h.feet), h.fold_root, _plain(h.test_pattern),
                               _plain(h.mirror_map), h.contact_height, h.contact_speed)
        return load_dataset(h.name, path=path, cache_dir=h.cache_dir, forward_axis=_plain(h.forward_axis),
                            download=h.download, synthetic=dict(h.synthetic) if h.synthetic else None, split=h.split,
                            folder=folder)

    def prepare_data(self) -> None:
        self.load_data()  # builds the cache (and downloads LAFAN1 if allowed) once, on one process

    def setup(self, stage: str | None = None) -> None:
        """Test windows for every stage; training and validation windows only when fitting or validating (a
        test run never builds the training set: ``eval.py`` on Bandai-Namco-2 would otherwise hold it in memory)."""
        if self.data is None:
            self.use_data(self.load_data())
        if stage in (None, "fit", "validate") and self.clip_windows is None:
            self._setup_fit()

    def use_data(self, data: MotionData) -> None:
        """Use ``data`` (e.g. :meth:`~inbetweening.data.clips.MotionData.in_joint_order` of :meth:`load_data`, for a
        checkpoint whose joints come in another order) instead of loading it; before :meth:`setup`."""
        h = self.hparams
        self.data, self.clip_windows = data, None
        self.test_set = _Windows(data.test_X[: h.max_eval_windows], data.test_Q[: h.max_eval_windows])

    def _setup_fit(self) -> None:
        h, data = self.hparams, self.data
        sk, axis = data.skeleton, data.forward_axis
        train_clips, val_clips = split_train_val(data.train, h.val_fraction)
        if h.extra:
            from inbetweening.training.other_rigs import other_rig_clips

            train_clips = train_clips + other_rig_clips(_plain(h.extra), sk, data.fps, h.cache_dir) * int(h.extra_repeat)
        cw = W.ClipWindows(train_clips, sk, h.train_window, h.train_offset, data.mirror if h.mirror else None)
        if h.max_train_windows:
            cw.starts = cw.starts[: h.max_train_windows]
        if len(cw) == 0:
            raise ValueError(f"data: no training window of {h.train_window} frames in dataset {h.name!r}")
        self.clip_windows = cw
        self.parts = None  # data.mix_parts: the joints mixed together, found once
        if h.mix_parts:
            feet = list(data.contact.indices(sk.names)) or self._feet_guess()
            upper = upper_body(sk.parents, feet)
            self.parts = upper_limbs(sk.parents, upper) if h.mix_parts == "limbs" else [upper]
        vX, vQ = W.prepare_windows(val_clips or train_clips[:1], sk, W.TEST_WINDOW, W.TEST_OFFSET, axis)
        vlim = h.max_val_windows or h.max_eval_windows
        self.val_set = _Windows(vX[:vlim], vQ[:vlim])
        self.held_out = (vX, vQ)  # every validation window, uncapped (the calibration's)

    def calibration_windows(self, limit: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Validation windows (never the test set), ``root (N, T, 3), local_q (N, T, J, 4)``: at most ``limit``,
        evenly spaced over all of them (not capped by ``max_val_windows``), for the do-no-harm blend
        (:func:`inbetweening.predictor.calibration.fit_blend`); after ``setup("fit")``."""
        vX, vQ = self.held_out
        idx = np.arange(len(vX))
        if limit and limit < len(idx):
            idx = np.linspace(0, len(vX) - 1, int(limit)).round().astype(int)
        return vX[idx, :, 0], vQ[idx]

    def test_benchmark_set(self) -> W.BenchmarkSet:
        """The (possibly capped) test windows as a :class:`~inbetweening.data.windows.BenchmarkSet`."""
        d = self.data
        n = len(self.test_set)
        return W.BenchmarkSet(d.test_X[:n], d.test_Q[:n], d.skeleton, d.pos_mean, d.pos_std)

    @property
    def skeleton(self):
        return self.data.skeleton

    def model_kwargs(self) -> dict:
        """Plain values the LightningModule needs from the data: the predictor's settings the data decides
        (:meth:`~inbetweening.predictor.settings.PredictorSettings.from_data`: skeleton, statistics, name, conventions,
        training window) and the benchmark lengths."""
        return {**PredictorSettings.from_data(self.data, self.hparams.train_window),
                "val_lengths": list(self.hparams.val_lengths), "test_lengths": list(self.hparams.test_lengths)}

    # ------------------------------------------------------------------ batches
    def collate_train(self, items: list) -> dict:
        """``items``: window indices, or ``(epoch, batch number, index)`` tuples from the training sampler, whose
        first two seed this batch's random draws (transition lengths, joint masks): resumable, reproducible."""
        h = self.hparams
        if items and isinstance(items[0], (tuple, list)):
            gen = torch.Generator().manual_seed(mix_seed(h.seed, items[0][0], items[0][1], 7))
            idx = [i for _, _, i in items]
        else:
            gen, idx = None, list(items)
        root, q = self._train_windows(idx, gen)
        if self.parts is not None:
            q = mix_body_parts(gen, q, self.parts)
        b, w, j, _ = q.shape
        if self.mask_name == "joints":
            known = self.joint_gaps.known(b, w, j, generator=gen)
            return {"root": root, "q": q, "known": known, "loss_mask": ~known}
        c, n, keys = draw_task(gen, b, (int(h.transition_min), int(h.transition_max)), h.transition_per == "sample",
                               (int(h.context_min), int(h.context_max)), int(h.keyframes_max), float(h.keyframe_prob))
        if keys is not None and float(h.partial_prob) > 0:
            keys = partial_keys(gen, keys, self.data.skeleton.parents, float(h.partial_prob))
        root, q, known = task_window(root, q, c, n, keys)
        return {"root": root, "q": q, "known": known, "loss_mask": ~known, "n_trans": n, "n_context": c}

    def _train_windows(self, idx: list[int], gen: torch.Generator | None) -> tuple[torch.Tensor, torch.Tensor]:
        """Training windows ``root (B, W, 3), q (B, W, J, 4)`` (float64, the clips' frame) of window numbers ``idx``,
        each mirrored with probability 0.5 when ``mirror`` is on and played at a drawn speed when ``speed`` is set."""
        flip = sp = None
        if self.hparams.mirror:
            flip = (torch.rand(len(idx), generator=gen) < 0.5).numpy()
        if self.hparams.speed:
            lo, hi = (np.log(float(v)) for v in self.hparams.speed)
            n = 2 if self.hparams.speed_vary else 1
            sp = np.exp(lo + (hi - lo) * torch.rand(len(idx), n, generator=gen, dtype=torch.float64).numpy())
        root, q = self.clip_windows.windows(idx, flip, sp)
        return torch.from_numpy(root), torch.from_numpy(q)

    def _feet_guess(self) -> list[int]:
        """A dataset without foot joints: the deepest joint of each of the root's two longest chains stands in."""
        parents = self.data.skeleton.parents
        depth = [0] * len(parents)
        for c in range(1, len(parents)):
            depth[c] = depth[int(parents[c])] + 1
        leaves = [c for c in range(len(parents)) if c not in set(int(p) for p in parents)]
        return sorted(leaves, key=lambda c: -depth[c])[:2]

    def _n_train(self) -> int:
        return len(self.clip_windows)

    def train_dataloader(self) -> DataLoader:
        h = self.hparams
        sampler = EpochPermutation(self._n_train(), h.seed, *rank_world())
        return ResumableLoader(IndexDataset(self._n_train()), batch_sampler=ResumableBatchSampler(sampler, h.batch_size),
                               collate_fn=self.collate_train, num_workers=h.num_workers,
                               persistent_workers=h.num_workers > 0, progress=self._epoch_progress,
                               generator=self._loader_generator(1))

    def steps_per_epoch(self, world_size: int = 1) -> int:
        """Training batches per epoch and process (the length of :meth:`train_dataloader`)."""
        return -(-(self._n_train() // world_size) // int(self.hparams.batch_size))

    def _epoch_progress(self) -> int:
        """Training batches completed in the current epoch (what a checkpoint written now has trained)."""
        trainer = getattr(self, "trainer", None)
        if trainer is None:
            return 0
        return int(trainer.fit_loop.epoch_loop.batch_progress.current.processed)

    def _eval_loader(self, ds: Dataset) -> DataLoader:
        sampler = None
        if rank_world()[1] > 1:
            # each window scored exactly once across the processes (no padding duplicates): the metrics, synced
            # by torchmetrics, equal a single process's on the same windows
            from lightning.pytorch.overrides.distributed import UnrepeatedDistributedSampler

            sampler = UnrepeatedDistributedSampler(ds, shuffle=False)
        return DataLoader(ds, batch_size=self.hparams.eval_batch_size, shuffle=False, sampler=sampler,
                          num_workers=self.hparams.num_workers, generator=self._loader_generator(2))

    def _loader_generator(self, stream: int) -> torch.Generator:
        """A loader's own generator: creating its iterator (a seed draw, each epoch) never touches the global torch
        RNG, whose state -- the dropout masks -- a checkpoint saves and a resume restores."""
        return torch.Generator().manual_seed(mix_seed(self.hparams.seed, stream, 11))

    def val_dataloader(self) -> DataLoader:
        return self._eval_loader(self.val_set)

    def test_dataloader(self) -> DataLoader:
        return self._eval_loader(self.test_set)
