"""LightningDataModule: masked in-betweening windows from any dataset of :mod:`inbetweening.data.datasets`.

Training windows (50 frames every 20, normalised as in the benchmark) are encoded once into one
in-memory ``(N, W, J, 7)`` tensor; a batch is a gather from it, so there is no per-item file I/O.
Each training batch gets 10 context frames, a transition of random length (``transition_min`` ..
``transition_max``, drawn per batch or per sample) and the target keyframe; frames after the
target are not part of the task.  Validation and test batches are the benchmark's 65-frame windows
(validation: a held-out part of the training clips; test: the dataset's test split).

Batch keys (train): ``gt (B, T, J, 7)``, ``known (B, T, J)`` bool, ``loss_mask (B, T, J)`` bool,
``n_trans (B,)``.  Batch keys (val/test): ``root (B, 65, 3)``, ``q (B, 65, J, 4)`` float64.
"""
from __future__ import annotations

import lightning as L
import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset, Sampler

from inbetweening.data.datasets import MotionData, load_dataset
from inbetweening.evaluation import benchmark as B
from inbetweening.predictor.inference import window_features
from inbetweening.predictor.masks import joints_known
from inbetweening.training.windows import ClipWindows, draw_task, task_window


class _Index(Dataset):
    """Items are whatever the batch sampler asks for: ``(epoch, batch number, window index)`` tuples."""

    def __init__(self, n: int):
        self.n = n

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, i):
        return i


def _mix(*ints: int) -> int:
    """A 63-bit seed from several integers (stable across runs and processes)."""
    h = 1469598103934665603
    for v in ints:
        h = ((h ^ (int(v) & 0xFFFFFFFFFFFFFFFF)) * 1099511628211) & 0x7FFFFFFFFFFFFFFF
    return h


def _rank_world() -> tuple[int, int]:
    """``(rank, world size)`` of the running process group, ``(0, 1)`` outside distributed runs."""
    if torch.distributed.is_available() and torch.distributed.is_initialized():
        return torch.distributed.get_rank(), torch.distributed.get_world_size()
    return 0, 1


class EpochPermutation(Sampler[int]):
    """The training windows in an order that is a pure function of ``(seed, epoch)``; under DDP each process
    takes its share (``rank::world``, equal counts).  Lightning calls :meth:`set_epoch` at each epoch start."""

    def __init__(self, n: int, seed: int, rank: int = 0, world: int = 1):
        self.n, self.seed, self.rank, self.world, self.epoch = n, int(seed), rank, world, 0

    def set_epoch(self, epoch: int) -> None:
        self.epoch = int(epoch)

    def __iter__(self):
        g = torch.Generator().manual_seed(_mix(self.seed, self.epoch))
        order = torch.randperm(self.n, generator=g)
        per = self.n // self.world
        return iter(order[self.rank * per : (self.rank + 1) * per].tolist() if self.world > 1 else order.tolist())

    def __len__(self) -> int:
        return self.n // self.world


class ResumableBatchSampler:
    """Batches of :class:`EpochPermutation`, each item tagged ``(epoch, batch number, index)`` so the collate
    draws its random numbers from a generator seeded by them; ``skip`` batches are left out of the next epoch
    iterated (a mid-epoch resume)."""

    def __init__(self, sampler: EpochPermutation, batch_size: int):
        self.sampler, self.batch_size, self.skip = sampler, int(batch_size), 0

    def __iter__(self):
        epoch, idx = self.sampler.epoch, list(self.sampler)
        skip, self.skip = self.skip, 0
        for b in range(skip, len(self)):
            yield [(epoch, b, i) for i in idx[b * self.batch_size : (b + 1) * self.batch_size]]

    def __len__(self) -> int:
        return -(-len(self.sampler) // self.batch_size)


class _LazyIterator:
    """An iterator that makes the real one (``make()``) at its first ``next()``."""

    def __init__(self, make):
        self._make, self._it = make, None

    def __iter__(self):
        return self

    def __next__(self):
        if self._it is None:
            self._it = self._make()
        return next(self._it)


class ResumableLoader(DataLoader):
    """A training DataLoader whose position is saved in Lightning checkpoints (``state_dict``): after a resume
    mid-epoch, the epoch continues with the batch after the last one trained, in the same order."""

    def __init__(self, *args, progress=None, **kwargs):
        super().__init__(*args, **kwargs)
        self._progress = progress  # () -> batches trained so far in the current epoch

    def __iter__(self):
        # Lightning creates the epoch's iterator before it calls ``set_epoch``; with worker processes that iterator
        # starts prefetching batches at once, i.e. from the previous epoch's order (the first epoch after a resume).
        # So the real iterator is made at the first ``next()``, once the sampler knows its epoch.
        return _LazyIterator(super().__iter__)

    def state_dict(self) -> dict:
        return {"epoch": int(self.batch_sampler.sampler.epoch), "batches": int(self._progress() if self._progress else 0)}

    def load_state_dict(self, state: dict) -> None:
        self.batch_sampler.sampler.set_epoch(int(state["epoch"]))
        self.batch_sampler.skip = int(state["batches"])


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
    """Built by ``hydra.utils.instantiate(cfg.data, mask=..., joint_mask=..., seed=...)``: ``conf/data/*.yaml``
    hold exactly these arguments (the values live there, so none has a default here) except the last three,
    which come from the ``mask`` group and the run's ``seed``.

    Args:
        name, path, cache_dir, forward_axis, synthetic, download, split: the dataset (see
            :func:`inbetweening.data.datasets.load_dataset`); ``split`` names one of its spec's split rules
            (``standard``; ``bandai_namco`` also has ``content``).  Validation clips come from its training part.
        batch_size, eval_batch_size, num_workers: loaders (``eval_batch_size``: validation and test).
        val_fraction: share of the training clips held out for validation.
        transition_min, transition_max, transition_per: transition lengths drawn for training batches
            (per ``batch`` or per ``sample``).
        train_window, train_offset: training windows (frames, stride).
        sampling: ``windows`` (cut once and encoded into one tensor) or ``clips`` (cut from the clips per batch:
            any stride without the memory of a window tensor; needed for ``mirror``).
        context_min, context_max: context frames per training sample (``10, 10``: the benchmark's; ``1, 10``
            trains for keyframes alone too).
        keyframes_max, keyframe_prob: with probability ``keyframe_prob`` a sample gets ``1..keyframes_max`` extra
            known frames inside its transition.
        mirror: mirror each training window left/right with probability 0.5 (the dataset's mirror map; ``sampling:
            clips``).
        speed: ``[lo, hi]`` play each training window at a speed drawn uniformly in that range (time warp: faster
            versions of the training motions; ``sampling: clips``; capped where the clip ends); ``None``: off.
        val_lengths, test_lengths: transition lengths the validation and test benchmarks score (passed on to
            the LightningModule by :meth:`model_kwargs`).
        max_train_windows, max_eval_windows, max_val_windows: caps for quick runs (``None``: all windows;
            ``max_eval_windows`` caps validation and test, ``max_val_windows`` validation only).
        mask: ``zero`` | ``lerp`` | ``joints``; ``joint_mask``: the gap settings of ``mask=joints``.
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
        batch_size: int,
        eval_batch_size: int,
        num_workers: int,
        val_fraction: float,
        transition_min: int,
        transition_max: int,
        transition_per: str,
        train_window: int,
        train_offset: int,
        sampling: str,
        context_min: int,
        context_max: int,
        keyframes_max: int,
        keyframe_prob: float,
        mirror: bool,
        speed: list[float] | None,
        val_lengths: list[int],
        test_lengths: list[int],
        max_train_windows: int | None,
        max_eval_windows: int | None,
        max_val_windows: int | None,
        mask: str,
        joint_mask: dict | None,
        seed: int,
    ):
        super().__init__()
        self.save_hyperparameters(logger=False)  # the module logs the resolved data conventions
        self.data: MotionData | None = None
        self.train_feats: torch.Tensor | None = None
        self.clip_windows: ClipWindows | None = None

    # ------------------------------------------------------------------ setup
    def _load(self) -> MotionData:
        h = self.hparams
        return load_dataset(h.name, path=h.path, cache_dir=h.cache_dir, forward_axis=h.forward_axis,
                            download=h.download, synthetic=dict(h.synthetic) if h.synthetic else None, split=h.split)

    def prepare_data(self) -> None:
        self._load()  # builds the cache (and downloads LAFAN1 if allowed) once, on one process

    def setup(self, stage: str | None = None) -> None:
        """Test windows for every stage; training and validation windows only when fitting or validating (a
        test run never builds the training set: ``eval.py`` on Bandai-Namco-2 would otherwise hold it in memory)."""
        h = self.hparams
        if self.data is None:
            self.data = data = self._load()
            self.test_set = _Windows(data.test_X[: h.max_eval_windows], data.test_Q[: h.max_eval_windows])
        if stage in (None, "fit", "validate") and self.train_feats is None and self.clip_windows is None:
            self._setup_fit()

    def _setup_fit(self) -> None:
        h, data = self.hparams, self.data
        sk, axis = data.skeleton, data.forward_axis
        train_clips, val_clips = split_train_val(data.train, h.val_fraction)
        if h.sampling == "clips":
            cw = ClipWindows(train_clips, sk, h.train_window, h.train_offset, axis, data.mirror if h.mirror else None)
            if h.max_train_windows:
                cw.starts = cw.starts[: h.max_train_windows]
            n = len(cw)
        else:
            X, Q = B.prepare_windows(train_clips, sk, h.train_window, h.train_offset, axis)
            if h.max_train_windows:
                X, Q = X[: h.max_train_windows], Q[: h.max_train_windows]
            n = len(X)
        if n == 0:
            raise ValueError(f"data: no training window of {h.train_window} frames in dataset {h.name!r}")
        if h.sampling == "clips":
            self.clip_windows = cw
        else:
            self.train_feats = self._encode_in_chunks(X[:, :, 0], Q)
        vX, vQ = B.prepare_windows(val_clips or train_clips[:1], sk, B.TEST_WINDOW, B.TEST_OFFSET, axis)
        vlim = h.max_val_windows or h.max_eval_windows
        self.val_set = _Windows(vX[:vlim], vQ[:vlim])

    def _encode_in_chunks(self, root, q, chunk: int = 1024) -> torch.Tensor:
        """Features of every training window, ``chunk`` windows at a time (the float64 FK of a whole dataset at
        once would hold several GB of intermediates); identical to encoding them all at once."""
        d = self.data
        first = window_features(root[:chunk], q[:chunk], d.skeleton, d.pos_mean, d.pos_std)
        out = torch.empty((len(root), *first.shape[1:]), dtype=first.dtype)
        out[:chunk] = first
        for s in range(chunk, len(root), chunk):
            out[s : s + chunk] = window_features(root[s : s + chunk], q[s : s + chunk], d.skeleton, d.pos_mean,
                                                 d.pos_std)
        return out

    def test_benchmark_set(self) -> B.BenchmarkSet:
        """The (possibly capped) test windows as a :class:`~inbetweening.evaluation.benchmark.BenchmarkSet`."""
        d = self.data
        n = len(self.test_set)
        return B.BenchmarkSet(d.test_X[:n], d.test_Q[:n], d.skeleton, d.pos_mean, d.pos_std)

    @property
    def skeleton(self):
        return self.data.skeleton

    def model_kwargs(self) -> dict:
        """Plain values the LightningModule needs from the data (skeleton, statistics, name)."""
        d = self.data
        return {"skeleton": d.skeleton.to_dict(), "pos_mean": d.pos_mean.tolist(), "pos_std": d.pos_std.tolist(),
                "dataset": d.name, "forward_axis": list(d.forward_axis), "fps": float(d.fps),
                "train_window": int(self.hparams.train_window), "val_lengths": list(self.hparams.val_lengths),
                "test_lengths": list(self.hparams.test_lengths)}

    # ------------------------------------------------------------------ batches
    def collate_train(self, items: list) -> dict:
        """``items``: window indices, or ``(epoch, batch number, index)`` tuples from the training sampler, whose
        first two seed this batch's random draws (transition lengths, joint masks): resumable, reproducible."""
        h = self.hparams
        if items and isinstance(items[0], (tuple, list)):
            gen = torch.Generator().manual_seed(_mix(h.seed, items[0][0], items[0][1], 7))
            idx = [i for _, _, i in items]
        else:
            gen, idx = None, list(items)
        gt = self._train_features(idx, gen)
        b, w, j, _ = gt.shape
        if h.mask == "joints":
            jm = dict(h.joint_mask or {})
            known = joints_known(b, w, j, int(jm.get("gap_min", 10)), int(jm.get("gap_max", 200)),
                                 float(jm.get("frac_min", 0.1)), float(jm.get("frac_max", 0.3)), generator=gen)
            return {"gt": gt, "known": known, "loss_mask": ~known}
        c, n, keys = draw_task(gen, b, (int(h.transition_min), int(h.transition_max)), h.transition_per == "sample",
                               (int(h.context_min), int(h.context_max)), int(h.keyframes_max), float(h.keyframe_prob))
        gt, known = task_window(gt, c, n, keys)
        return {"gt": gt, "known": known, "loss_mask": ~known, "n_trans": n}

    def _train_features(self, idx: list[int], gen: torch.Generator | None) -> torch.Tensor:
        """Features ``(B, W, J, F)`` of training windows ``idx``: gathered from the encoded windows, or (``sampling:
        clips``) cut from the clips now, each mirrored with probability 0.5 when ``mirror`` is on and played at a
        drawn speed when ``speed`` is set."""
        if self.clip_windows is None:
            return self.train_feats[torch.as_tensor(idx)]
        flip = sp = None
        if self.hparams.mirror:
            flip = (torch.rand(len(idx), generator=gen) < 0.5).numpy()
        if self.hparams.speed:
            lo, hi = (float(v) for v in self.hparams.speed)
            sp = (lo + (hi - lo) * torch.rand(len(idx), generator=gen, dtype=torch.float64)).numpy()
        root, q = self.clip_windows.windows(idx, flip, sp)
        d = self.data
        return window_features(root, q, d.skeleton, d.pos_mean, d.pos_std)

    def _n_train(self) -> int:
        return len(self.clip_windows) if self.clip_windows is not None else len(self.train_feats)

    def train_dataloader(self) -> DataLoader:
        h = self.hparams
        sampler = EpochPermutation(self._n_train(), h.seed, *_rank_world())
        return ResumableLoader(_Index(self._n_train()), batch_sampler=ResumableBatchSampler(sampler, h.batch_size),
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
        if _rank_world()[1] > 1:
            # each window scored exactly once across the processes (no padding duplicates): the metrics, synced
            # by torchmetrics, equal a single process's on the same windows
            from lightning.pytorch.overrides.distributed import UnrepeatedDistributedSampler

            sampler = UnrepeatedDistributedSampler(ds, shuffle=False)
        return DataLoader(ds, batch_size=self.hparams.eval_batch_size, shuffle=False, sampler=sampler,
                          num_workers=self.hparams.num_workers, generator=self._loader_generator(2))

    def _loader_generator(self, stream: int) -> torch.Generator:
        """A loader's own generator: creating its iterator (a seed draw, each epoch) never touches the global torch
        RNG, whose state -- the dropout masks -- a checkpoint saves and a resume restores."""
        return torch.Generator().manual_seed(_mix(self.hparams.seed, stream, 11))

    def val_dataloader(self) -> DataLoader:
        return self._eval_loader(self.val_set)

    def test_dataloader(self) -> DataLoader:
        return self._eval_loader(self.test_set)
