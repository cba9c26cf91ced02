"""Resumable, reproducible sampling of training batches: the window order is a pure function of (seed, epoch), each
batch carries (epoch, batch number) so its random draws come from its own generator, and the loader's position is
saved in checkpoints (a resumed epoch continues with the next batch)."""
from __future__ import annotations

import torch
from torch.utils.data import DataLoader, Dataset, Sampler

__all__ = ["EpochPermutation", "IndexDataset", "ResumableBatchSampler", "ResumableLoader", "mix_seed", "rank_world"]


class IndexDataset(Dataset):
    """Items are whatever the batch sampler asks for: ``(epoch, batch number, window index)`` tuples."""

    def __init__(self, n: int):
        self.n = n

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, i):
        return i


def mix_seed(*ints: int) -> int:
    """A 63-bit seed from several integers (stable across runs and processes)."""
    h = 1469598103934665603
    for v in ints:
        h = ((h ^ (int(v) & 0xFFFFFFFFFFFFFFFF)) * 1099511628211) & 0x7FFFFFFFFFFFFFFF
    return h


def rank_world() -> tuple[int, int]:
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
        g = torch.Generator().manual_seed(mix_seed(self.seed, self.epoch))
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
