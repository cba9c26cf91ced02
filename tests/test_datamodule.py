"""The training data path: train/validation split, transition sampling (per batch / per sample), masks, and
batches that are a pure function of (seed, epoch, batch number) so a resumed run sees the same data."""
from __future__ import annotations

import inspect
import random
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf

from conftest import CONF_DIR, TINY, compose_cfg
from inbetweening.data import windows as W
from inbetweening.training.builders import make_datamodule, make_module
from inbetweening.training.datamodule import InbetweenDataModule, split_train_val

DATA = [o for o in TINY if o.startswith("data.")]


def _dm(tmp_path, cache_dir, *extra):
    cfg = compose_cfg("train", [*DATA, *extra], tmp_path, cache_dir)
    dm = make_datamodule(cfg)
    dm.setup("fit")
    return dm


def _batches(dm, epoch: int) -> list[dict]:
    loader = dm.train_dataloader()
    loader.batch_sampler.sampler.set_epoch(epoch)  # what Lightning does at each epoch start
    return list(loader)


def _order(dm, epoch: int) -> list[int]:
    loader = dm.train_dataloader()
    loader.batch_sampler.sampler.set_epoch(epoch)
    return [i for items in loader.batch_sampler for *_, i in items]


def _same_batches(a: list[dict], b: list[dict]) -> bool:
    return len(a) == len(b) and all(x.keys() == y.keys() and all(torch.equal(x[k], y[k]) for k in x)
                                    for x, y in zip(a, b))


# ------------------------------------------------------------------------------------------ built from the config
FROM_OTHER_GROUPS = {"mask": "${mask}", "seed": "${seed}"}  # cfg.data's keys that take the run's own values


@pytest.mark.parametrize("data", sorted(p.stem for p in (Path(CONF_DIR) / "data").glob("*.yaml")))
def test_data_yamls_hold_exactly_the_data_modules_arguments(data, tmp_path):
    cfg = compose_cfg("train", [f"data={data}"], tmp_path, tmp_path)
    assert cfg.data._target_ == "inbetweening.training.datamodule.InbetweenDataModule"
    params = set(inspect.signature(InbetweenDataModule.__init__).parameters) - {"self"}
    assert set(cfg.data) - {"_target_"} == params
    raw = OmegaConf.to_container(cfg.data, resolve=False)
    for k, ref in FROM_OTHER_GROUPS.items():  # one source each: the mask group and the seed, never a copy
        assert raw[k] == ref, k


def test_data_module_is_instantiated_from_the_config_unmapped(tmp_path, cache_dir):
    """Every key of ``cfg.data`` reaches the constructor as it is (no setup: nothing is loaded)."""
    over = ["data.eval_batch_size=7", "data.val_fraction=0.25", "data.test_lengths=[5,10]", "data.train_offset=13",
            "data.max_val_windows=3", "data.transition_per=sample", "seed=5", "mask=joints", "mask.gap_min=4"]
    cfg = compose_cfg("train", [*DATA, *over], tmp_path, cache_dir)
    dm = make_datamodule(cfg)
    assert type(dm) is InbetweenDataModule and dm.data is None
    want = OmegaConf.to_container(cfg.data, resolve=True)
    assert set(dm.hparams) == set(want) - {"_target_"}
    for k in set(want) - {"_target_"}:
        assert dm.hparams[k] == want[k], k
    assert dm.hparams.eval_batch_size == 7 and dm.hparams.test_lengths == [5, 10] and dm.hparams.train_offset == 13
    assert isinstance(dm.hparams.test_lengths, list) and isinstance(dm.hparams.synthetic, dict)  # plain values
    assert dm.hparams.seed == 5 and dm.hparams.mask["name"] == "joints" and dm.hparams.mask["gap_min"] == 4
    assert dm.hparams.mask == OmegaConf.to_container(cfg.mask, resolve=True)
    assert dm.mask_name == "joints" and dm.joint_gaps.gap_min == 4 and dm.joint_gaps.gap_max == cfg.mask.gap_max


def test_benchmark_lengths_reach_the_module_through_the_data_module(tmp_path, cache_dir):
    over = ["data.val_lengths=[5,10]", "data.test_lengths=[7]"]
    cfg = compose_cfg("train", [*TINY, *over], tmp_path, cache_dir)
    dm = make_datamodule(cfg)
    dm.setup("fit")
    module = make_module(cfg, dm)
    assert list(module.hparams.val_lengths) == [5, 10] and list(module.hparams.test_lengths) == [7]
    assert list(module.val_bench.lengths) == [5, 10] and list(module.test_bench.lengths) == [7]


# ------------------------------------------------------------------------------------------ train/val split
def test_split_train_val_is_a_disjoint_deterministic_partition():
    clips = [SimpleNamespace(name=f"clip{i:03d}_subject{i % 4 + 1}") for i in range(50)]
    train, val = split_train_val(clips, 0.1)
    names_t, names_v = {c.name for c in train}, {c.name for c in val}
    assert not names_t & names_v
    assert names_t | names_v == {c.name for c in clips}
    assert len(train) + len(val) == len(clips)  # no clip twice
    assert len(val) == 5  # about val_fraction of the clips
    shuffled = clips[:]
    random.Random(3).shuffle(shuffled)  # the split depends on the clip names, not on the listing order
    train2, val2 = split_train_val(shuffled, 0.1)
    assert {c.name for c in val2} == names_v and {c.name for c in train2} == names_t
    assert len(split_train_val(clips, 0.25)[1]) in (12, 13)
    assert split_train_val(clips, 0.0) == (clips, [])
    few = clips[:8]  # fewer clips than 1 / val_fraction: still one held out, never validation on training clips
    assert [len(part) for part in split_train_val(few, 0.1)] == [7, 1]


def test_validation_windows_come_only_from_validation_clips(tmp_path, cache_dir):
    dm = _dm(tmp_path, cache_dir, "data.max_eval_windows=null")  # 8 training clips, val_fraction 0.1
    data, sk, axis = dm.data, dm.data.skeleton, dm.data.forward_axis
    train_clips, val_clips = split_train_val(data.train, dm.hparams.val_fraction)
    assert len(val_clips) == 1 and len(train_clips) == len(data.train) - 1
    vX, vQ = W.prepare_windows(val_clips, sk, W.TEST_WINDOW, W.TEST_OFFSET, axis)
    assert torch.equal(dm.val_set.q, torch.from_numpy(vQ))
    assert torch.equal(dm.val_set.root, torch.from_numpy(vX[:, :, 0]))
    # and no validation window is one of the training clips' windows
    tX, tQ = W.prepare_windows(train_clips, sk, W.TEST_WINDOW, W.TEST_OFFSET, axis)
    for q in dm.val_set.q.numpy():
        assert not np.any(np.all(np.abs(tQ - q) < 1e-9, axis=(1, 2, 3)))
    # the training windows are the training clips' 50-frame windows (their own frame), nothing from the validation clips
    X, Q = W.extract_windows(train_clips, sk, dm.hparams.train_window, dm.hparams.train_offset)
    root, q = dm.clip_windows.windows(np.arange(len(dm.clip_windows)))
    assert np.array_equal(root, X[:, :, 0]) and np.array_equal(q, Q)


# ------------------------------------------------------------------------------------------ transitions
def test_transition_per_sample(tmp_path, cache_dir):
    dm = _dm(tmp_path, cache_dir, "data.transition_per=sample", "data.transition_min=5", "data.transition_max=30")
    n_past, lo, hi = W.N_PAST, 5, 30
    idx = list(range(len(dm.clip_windows)))
    batch = dm.collate_train([(0, 0, i) for i in idx])
    assert set(batch) == {"root", "q", "known", "loss_mask", "n_trans", "n_context"}
    root, q, known, loss_mask, n = batch["root"], batch["q"], batch["known"], batch["loss_mask"], batch["n_trans"]
    assert torch.equal(batch["n_context"], torch.full((len(idx),), n_past))  # every sample's context: 10 frames
    b, t, j, _ = q.shape
    assert root.shape == (b, t, 3) and root.dtype == q.dtype == torch.float64
    assert b == len(idx) and n.shape == (b,)
    assert int(n.min()) >= lo and int(n.max()) <= hi
    assert len(set(n.tolist())) > 5  # lengths vary within the batch
    assert t == n_past + int(n.max()) + 1
    src_root, src_q = (torch.from_numpy(a) for a in dm.clip_windows.windows(idx))
    for i in range(b):
        target = n_past + int(n[i])
        frame_known = torch.tensor([f < n_past or f >= target for f in range(t)])
        assert torch.equal(known[i], frame_known[:, None].expand(t, j)), i
        # the sample's own frames up to its target, then the target repeated
        assert torch.equal(root[i, : target + 1], src_root[i, : target + 1]), i
        assert torch.equal(q[i, : target + 1], src_q[i, : target + 1]), i
        assert torch.equal(root[i, target:], root[i, target : target + 1].expand(t - target, 3)), i
        assert torch.equal(q[i, target:], q[i, target : target + 1].expand(t - target, j, 4)), i
        assert not loss_mask[i, target:].any() and not loss_mask[i, :n_past].any(), i
        assert loss_mask[i, n_past:target].all(), i
    assert torch.equal(loss_mask, ~known)
    # over many batches the lengths cover exactly min..max, both ends included
    drawn = torch.cat([dm.collate_train([(0, k, i) for i in idx])["n_trans"] for k in range(30)])
    assert set(drawn.tolist()) == set(range(lo, hi + 1))


def test_transition_per_batch_gives_one_length_per_batch(tmp_path, cache_dir):
    dm = _dm(tmp_path, cache_dir, "data.transition_per=batch", "data.transition_min=5", "data.transition_max=30")
    n_past = W.N_PAST
    lengths = []
    for epoch in range(4):
        for batch in _batches(dm, epoch):
            n = batch["n_trans"]
            assert len(set(n.tolist())) == 1
            t = batch["q"].shape[1]
            assert batch["root"].shape[1] == t
            assert t == n_past + int(n[0]) + 1  # context, transition, target: nothing after it
            assert torch.equal(batch["loss_mask"], ~batch["known"])
            assert batch["known"][:, :n_past].all() and batch["known"][:, -1].all()
            assert not batch["known"][:, n_past:-1].any()
            lengths.append(int(n[0]))
    assert min(lengths) >= 5 and max(lengths) <= 30
    assert len(set(lengths)) > 3  # but it varies from batch to batch


# ------------------------------------------------------------------------------------------ reproducible batches
@pytest.mark.parametrize("extra", [["data.transition_per=batch"], ["data.transition_per=sample"],
                                   ["mask=joints", "mask.gap_min=5", "mask.gap_max=40"]])
def test_batches_are_a_function_of_seed_and_epoch(extra, tmp_path, cache_dir):
    """Not of the global RNG: what a checkpoint does not hold cannot change the data of a resumed epoch."""
    dm = _dm(tmp_path, cache_dir, *extra)
    torch.manual_seed(0)
    e1 = _batches(dm, 1)
    torch.manual_seed(123)
    torch.rand(1000)
    assert _same_batches(_batches(dm, 1), e1)
    assert _same_batches(_batches(_dm(tmp_path, cache_dir, *extra), 1), e1)  # a new process: a new data module
    seven = _dm(tmp_path, cache_dir, *extra, "seed=7")
    assert not _same_batches(_batches(dm, 2), e1)
    assert not _same_batches(_batches(seven, 1), e1)
    # each of order and draws depends on both the epoch and the seed
    assert _order(dm, 1) != _order(dm, 2) and _order(dm, 1) != _order(seven, 1)

    def draws(module, epoch):  # the same windows in the same batches, tagged with another seed or epoch
        return [module.collate_train([(epoch, k, i) for i in range(8)]) for k in range(6)]

    assert _same_batches(draws(dm, 1), draws(dm, 1))
    assert not _same_batches(draws(dm, 1), draws(dm, 2)) and not _same_batches(draws(dm, 1), draws(seven, 1))
    # the same windows each epoch, once each
    idx = [i for batch in dm.train_dataloader().batch_sampler for _, _, i in batch]
    assert sorted(idx) == list(range(len(dm.clip_windows)))


def test_batches_with_worker_processes_equal_in_process_batches(tmp_path, cache_dir):
    extra = ["data.transition_per=sample"]
    want = _batches(_dm(tmp_path, cache_dir, *extra), 1)
    workers = _dm(tmp_path, cache_dir, *extra, "data.num_workers=1")
    assert _same_batches(_batches(workers, 1), want)
    # Lightning's order: the epoch's iterator is created, then set_epoch is called, then batches are drawn (a
    # worker process must not have prefetched batches of the previous epoch's order by then)
    loader = workers.train_dataloader()
    it = iter(loader)
    loader.batch_sampler.sampler.set_epoch(1)
    assert _same_batches(list(it), want)


def test_test_stage_builds_no_training_windows(tmp_path, cache_dir):
    """``eval.py`` sets the data module up for testing only: the training set is never built (memory)."""
    cfg = compose_cfg("train", DATA, tmp_path, cache_dir)
    dm = make_datamodule(cfg)
    dm.setup("test")
    assert dm.clip_windows is None and len(dm.test_set) > 0
    dm.setup("fit")  # fitting afterwards still gets its windows
    assert dm.clip_windows is not None and len(dm.clip_windows) > 0 and len(dm.val_set) > 0




def test_max_train_windows_keeps_the_first_training_windows(tmp_path, cache_dir):
    full = _dm(tmp_path, cache_dir)
    capped = _dm(tmp_path, cache_dir, "data.max_train_windows=5")
    assert len(full.clip_windows) > 5 and len(capped.clip_windows) == 5
    a, b = full.clip_windows.windows(range(5)), capped.clip_windows.windows(range(5))
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    idx = [i for batch in capped.train_dataloader().batch_sampler for _, _, i in batch]
    assert sorted(idx) == list(range(5))
