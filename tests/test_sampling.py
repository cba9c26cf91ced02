"""``inbetweening.training.sampling``: the training order is a pure function of (seed, epoch), shares are disjoint
under DDP, a resumed epoch skips exactly the batches already trained, and the loader's position round-trips."""
from __future__ import annotations

import torch

from inbetweening.training.sampling import EpochPermutation, IndexDataset, ResumableBatchSampler, ResumableLoader, mix_seed


def test_order_is_a_function_of_seed_and_epoch():
    a, b = EpochPermutation(50, seed=3), EpochPermutation(50, seed=3)
    assert list(a) == list(b) and sorted(a) == list(range(50))
    first = list(a)
    a.set_epoch(1)
    assert list(a) != first and sorted(a) == list(range(50))
    assert list(EpochPermutation(50, seed=4)) != first


def test_ranks_take_disjoint_equal_shares():
    shares = [list(EpochPermutation(51, seed=1, rank=r, world=3)) for r in range(3)]
    assert all(len(s) == 17 for s in shares)
    assert len(set().union(*shares)) == 51  # 51 // 3 each, no window twice
    assert sum(shares, []) == list(EpochPermutation(51, seed=1))[:51]


def test_batches_carry_epoch_and_number_and_a_resume_skips_the_trained_ones():
    sampler = ResumableBatchSampler(EpochPermutation(10, seed=0), batch_size=4)
    full = list(sampler)
    assert len(sampler) == 3 and [len(b) for b in full] == [4, 4, 2]
    assert all(item[:2] == (0, k) for k, batch in enumerate(full) for item in batch)
    sampler.skip = 2
    assert list(sampler) == full[2:]
    assert list(sampler) == full  # the skip applies to one epoch only


def test_loader_position_round_trips():
    done = {"n": 0}
    loader = ResumableLoader(IndexDataset(10), batch_sampler=ResumableBatchSampler(EpochPermutation(10, seed=0), 3),
                             collate_fn=lambda items: items, progress=lambda: done["n"])
    loader.batch_sampler.sampler.set_epoch(2)
    done["n"] = 2
    state = loader.state_dict()
    assert state == {"epoch": 2, "batches": 2}
    fresh = ResumableLoader(IndexDataset(10), batch_sampler=ResumableBatchSampler(EpochPermutation(10, seed=0), 3),
                            collate_fn=lambda items: items)
    fresh.load_state_dict(state)
    assert list(fresh) == list(loader)[2:]


def test_mix_seed_is_stable_and_spreads():
    assert mix_seed(1, 2, 3) == mix_seed(1, 2, 3) and mix_seed(1, 2, 3) != mix_seed(1, 3, 2)
    assert 0 <= mix_seed(10**20, -5) < 2**63
    torch.Generator().manual_seed(mix_seed(7, 0, 0))  # usable as a seed
