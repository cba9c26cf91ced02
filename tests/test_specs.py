"""Dataset specs: the registry alone drives load_dataset (new BVH datasets, non-BVH readers), configs agree with it."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from inbetweening.data import windows as W
from inbetweening.data.bvh_writer import write_bvh
from inbetweening.data.clips import Clip
from inbetweening.data.datasets import load_dataset, resolve_path
from inbetweening.data.errors import DatasetError
from inbetweening.data.mirror import side_pairs
from inbetweening.data.specs import BN_CONTENTS, BN_TEST_CONTENTS, DATASETS, DatasetSpec, get_spec, lafan_split, register
from inbetweening.data.synthetic import NAMES, OFFSETS, PARENTS, generate_clip, make_bvh
from inbetweening.geometry.skeleton import Skeleton

LAFAN_MIRROR = side_pairs("Left{}", "UpLeg Leg Foot Toe Shoulder Arm ForeArm Hand")
CONF_DATA = Path(__file__).resolve().parents[1] / "conf" / "data"
MINI_RE = re.compile(r"^(?P<take>[a-z]+\d*)-(?P<actor>[A-Z])\.bvh$", re.IGNORECASE)


def mini_split(fname: str):
    """The test dataset's own rule: actor A and B train, actor C test, anything else skipped."""
    m = MINI_RE.match(fname)
    if not m:
        return None
    return {"A": "train", "B": "train", "C": "test"}.get(m.group("actor").upper())


def write_mini_folder(folder: Path, frames: int = 120) -> Path:
    """LAFAN-format BVH files named ``<take>-<actor>.bvh``, plus files the split rule must skip."""
    rng = np.random.default_rng(7)
    (folder / "nested").mkdir(parents=True)
    for i, actor in enumerate("AABBCCD"):
        sub = folder / "nested" if i % 2 else folder
        write_bvh(make_bvh(*generate_clip(rng, frames + 5 * i)), sub / f"take{i}-{actor}.bvh")
    (folder / "notes.txt").write_text("not a clip")
    write_bvh(make_bvh(*generate_clip(rng, frames)), folder / "calibration.bvh")  # no actor: skipped
    return folder


@pytest.fixture
def registry():
    """The registry, restored after the test (its registrations vanish)."""
    saved = dict(DATASETS)
    yield DATASETS
    DATASETS.clear()
    DATASETS.update(saved)


def test_a_registered_bvh_spec_loads_with_no_other_change(tmp_path, registry, monkeypatch):
    spec = register(DatasetSpec("mini", mini_split, (1, 0, 0), env_var="MINI_TEST_PATH", path_hint="make one"))
    assert registry["mini"] is spec and spec.forward_axis == (1.0, 0.0, 0.0)
    folder = write_mini_folder(tmp_path / "mini")
    d = load_dataset("mini", path=folder, cache_dir=tmp_path / "c")
    assert d.name == "mini" and d.forward_axis == (1.0, 0.0, 0.0) and d.fps == 30.0
    assert [c.name for c in d.train] == ["take0-A", "take1-A", "take2-B", "take3-B"]
    assert [c.name for c in d.test] == ["take4-C", "take5-C"]
    assert d.skeleton.names == NAMES and d.mirror == LAFAN_MIRROR  # derived from the Left*/Right* names
    # the spec's forward axis is the one the windows were normalised with (+X local turned to +X)
    X, Q = W.prepare_windows(d.test, d.skeleton, W.TEST_WINDOW, W.TEST_OFFSET, (1.0, 0.0, 0.0))
    np.testing.assert_array_equal(d.test_X, X)
    other, _ = W.prepare_windows(d.test, d.skeleton, W.TEST_WINDOW, W.TEST_OFFSET, (0.0, 0.0, 1.0))
    assert not np.allclose(other, X)
    # cached under the spec's name; the second load is served from the cache, identical
    assert [p.name.split("-")[0] for p in (tmp_path / "c" / "prepared").iterdir()] == ["mini"]
    again = load_dataset("mini", path=folder, cache_dir=tmp_path / "c")
    np.testing.assert_array_equal(again.test_X, d.test_X)
    assert again.mirror == d.mirror and again.fps == d.fps
    # the spec's environment variable and path hint
    monkeypatch.setenv("MINI_TEST_PATH", str(folder))
    assert load_dataset("mini", cache_dir=tmp_path / "c").summary() == d.summary()
    with pytest.raises(DatasetError, match=r"mini: .*nowhere does not exist; make one"):
        resolve_path("mini", tmp_path / "nowhere")


def test_builtin_lafan1_is_the_same_as_a_spec_with_its_fields(tmp_path, registry):
    folder = tmp_path / "l"
    folder.mkdir()
    rng = np.random.default_rng(3)
    for s in range(1, 6):
        write_bvh(make_bvh(*generate_clip(rng, 130)), folder / f"walk_subject{s}.bvh")
    lafan = get_spec("lafan1")
    register(DatasetSpec("copy", lafan.split, lafan.forward_axis, mirror=LAFAN_MIRROR))  # explicit: same map
    a = load_dataset("lafan1", path=folder, use_cache=False)
    b = load_dataset("copy", path=folder, use_cache=False)
    np.testing.assert_array_equal(a.test_X, b.test_X)
    np.testing.assert_array_equal(a.pos_std, b.pos_std)
    assert a.forward_axis == (0.0, 1.0, 0.0) and a.mirror == b.mirror == LAFAN_MIRROR


def _write_npz_clips(folder: Path) -> None:
    rng = np.random.default_rng(4)
    folder.mkdir()
    for i in range(6):
        q, root = generate_clip(rng, 110)
        with open(folder / f"clip{i}.NPZ", "wb") as f:  # upper-case extension: matched case-insensitively
            np.savez(f, local_q=q, root_pos=root)


def npz_reader(spec: DatasetSpec, path: Path):
    """A non-BVH source: one ``.npz`` per clip on the synthetic skeleton, no frame rate recorded."""
    skel = Skeleton(NAMES, PARENTS, OFFSETS)
    for f in sorted(path.iterdir()):
        if f.name.lower().endswith(".npz"):
            z = np.load(f)
            yield f.name, Clip(f.stem, z["local_q"], z["root_pos"]), skel, None


def test_a_reader_hook_plugs_in_a_non_bvh_source(tmp_path, registry):
    register(DatasetSpec("npz", lambda f: "test" if f.startswith("clip5") else "train", (0, 0, 1),
                         pattern="*.npz", fps=25.0, reader=npz_reader))
    folder = tmp_path / "npz"
    _write_npz_clips(folder)
    cache = tmp_path / "c"
    d = load_dataset("npz", path=folder, cache_dir=cache)
    assert d.fps == 25.0  # the reader knows none: the spec's
    assert len(d.train) == 5 and [c.name for c in d.test] == ["clip5"] and d.test_X.shape[1:] == (65, 22, 3)
    assert d.mirror == LAFAN_MIRROR
    # the cache key covers the spec's files (its pattern, matched case-insensitively): a changed clip is re-read
    q, root = generate_clip(np.random.default_rng(9), 110)
    with open(folder / "clip5.NPZ", "wb") as f:
        np.savez(f, local_q=q, root_pos=root)
    d2 = load_dataset("npz", path=folder, cache_dir=cache)
    assert len(list((cache / "prepared").iterdir())) == 2
    assert not np.allclose(d2.test[0].root_pos, d.test[0].root_pos)


def test_a_generated_spec_reads_no_path(tmp_path, registry):
    made = []

    def generate(folder, n=3):
        made.append(n)
        folder.mkdir(parents=True, exist_ok=True)
        rng = np.random.default_rng(n)
        for s in (1, 5):
            write_bvh(make_bvh(*generate_clip(rng, 120)), folder / f"g_subject{s}.bvh")
        return folder

    register(DatasetSpec("gen", lafan_split, (0, 0, 1), generate=generate))
    d = load_dataset("gen", path="/ignored", cache_dir=tmp_path / "c", synthetic={"n": 4})
    assert made == [4] and (tmp_path / "c" / "gen").is_dir() and len(d.train) == 1 and len(d.test) == 1


def test_fps_disagreeing_with_the_spec_warns(tmp_path, registry):
    register(DatasetSpec("fast", mini_split, (0, 0, 1), fps=60.0))
    with pytest.warns(UserWarning, match=r"fast: .* runs at 30 fps, the dataset spec says 60"):
        d = load_dataset("fast", path=write_mini_folder(tmp_path / "m"), use_cache=False)
    assert d.fps == 30.0  # the files' rate wins


def test_a_wrong_mirror_map_fails_on_load(tmp_path, registry):
    register(DatasetSpec("badmirror", mini_split, (0, 0, 1), mirror=(("LeftArm", "RightHand"),)))
    with pytest.raises(DatasetError, match=r"dataset 'badmirror' mirror map: \('LeftArm', 'RightHand'\)"):
        load_dataset("badmirror", path=write_mini_folder(tmp_path / "m"), use_cache=False)


def test_registry_errors(registry):
    with pytest.raises(ValueError, match="already registered"):
        register(DatasetSpec("lafan1", lafan_split, (0, 1, 0)))
    replaced = register(DatasetSpec("lafan1", lafan_split, (1, 0, 0)), replace=True)
    assert get_spec("lafan1") is replaced
    with pytest.raises(DatasetError, match=r"unknown dataset 'nope'; choose one of \['bandai_namco', 'lafan1', 'synthetic'\]"):
        get_spec("nope")
    with pytest.raises(ValueError, match="forward_axis must have 3 components"):
        DatasetSpec("x", lafan_split, (0, 1))
    spec = DatasetSpec("y", lafan_split, (0, 1, 0))
    with pytest.raises(AttributeError):
        spec.name = "z"  # frozen


def test_named_splits(tmp_path, registry):
    single = DatasetSpec("one", lafan_split, (0, 1, 0))
    assert single.splits == {"standard": lafan_split} and single.split is lafan_split  # one rule: the standard split
    bn = get_spec("bandai_namco")
    assert list(bn.splits)[:2] == ["standard", "content"] and bn.split is bn.split_rule("standard")
    assert bn.split_rule("content")("dataset-2_run_normal_001.bvh") == "test"
    assert sorted(n for n in bn.splits if n.startswith("holdout-")) == sorted(f"holdout-{c}" for c in BN_CONTENTS)
    assert len(BN_CONTENTS) == 10
    walk = bn.split_rule("holdout-walk")  # leave-one-content-out: that content alone is the test set
    assert [walk(f"dataset-2_{c}_normal_001.bvh") for c in ("walk", "walk-turn-left", "run")] == ["test", "train", "train"]
    # the folds: every content is held out by exactly one of them, fold-1 is the content split
    folds = [bn.split_rule(f"fold-{i}") for i in range(1, 6)]
    held = [[c for c in BN_CONTENTS if fold(f"dataset-2_{c}_normal_001.bvh") == "test"] for fold in folds]
    assert sorted(c for pair in held for c in pair) == sorted(BN_CONTENTS) and all(len(p) == 2 for p in held)
    assert sorted(held[0]) == sorted(BN_TEST_CONTENTS)
    with pytest.raises(DatasetError, match=r"^dataset 'one' has no split 'content'; its splits are \['standard'\]$"):
        single.split_rule("content")
    with pytest.raises(ValueError, match=r"splits must map names to split rules and include 'standard', got \['b'\]"):
        DatasetSpec("x", {"b": lafan_split}, (0, 1, 0))
    with pytest.raises(ValueError, match="splits must map names to split rules"):
        DatasetSpec("x", {"standard": "subject5"}, (0, 1, 0))
    # a registered spec with two splits: load_dataset picks one; a file only one split uses is still read
    by_actor = {"standard": mini_split, "reverse": lambda f: {"train": "test", "test": "train"}.get(mini_split(f) or "")}
    spec = register(DatasetSpec("mini2", by_actor, (1, 0, 0)))
    assert spec.reads("take0-A.bvh") and not spec.reads("calibration.bvh")
    folder = write_mini_folder(tmp_path / "m")
    a = load_dataset("mini2", path=folder, cache_dir=tmp_path / "c")
    b = load_dataset("mini2", path=folder, cache_dir=tmp_path / "c", split="reverse")
    assert [c.name for c in a.test] == [c.name for c in b.train] == ["take4-C", "take5-C"]
    assert (a.split, b.split) == ("standard", "reverse") and len(b.test) == 4


def test_a_spec_without_env_var_says_only_data_path():
    with pytest.raises(DatasetError, match=r"data.path is not set for dataset 'synthetic' \(set data.path=...\)$"):
        resolve_path("synthetic", None)
    with pytest.raises(DatasetError, match=r"\(set data.path=... or \$BANDAI_NAMCO_PATH\)"):
        resolve_path("bandai_namco", None)


@pytest.mark.parametrize("yaml_file", sorted(p for p in CONF_DATA.glob("*.yaml") if p.stem != "bvh"),
                         ids=lambda p: p.stem)
def test_every_data_config_names_a_spec_and_agrees_with_it(yaml_file):
    """Every registered dataset has its config (data=bvh derives its spec from the files: tests/test_bvh_folder.py)."""
    cfg = yaml.safe_load(yaml_file.read_text())
    spec = get_spec(cfg["name"])
    assert cfg["name"] == yaml_file.stem
    if spec.generate is not None:
        assert cfg["path"] is None and spec.env_var is None
    else:
        assert cfg["path"] == f"${{oc.env:{spec.env_var},${{paths.root_dir}}/{spec.default_path}}}"
    assert set(DATASETS) == {p.stem for p in CONF_DATA.glob("*.yaml")} - {"bvh"}  # every spec has its config


def test_builtin_specs():
    lafan, bn, syn = (get_spec(n) for n in ("lafan1", "bandai_namco", "synthetic"))
    assert (lafan.forward_axis, bn.forward_axis, syn.forward_axis) == ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (0.0, 0.0, 1.0))
    assert (lafan.fold_root, bn.fold_root, syn.fold_root) == (None, "joint_Root", None)
    assert (lafan.env_var, bn.env_var, syn.env_var) == ("LAFAN1_PATH", "BANDAI_NAMCO_PATH", None)
    assert lafan.download is not None and bn.download is None and syn.generate is not None
    assert lafan.mirror is bn.mirror is syn.mirror is None  # derived from the loaded names, see test_mirror.py
    assert bn.split("dataset-2_walk_normal_010.bvh") == "test" and lafan.split("x_subject2.bvh") == "train"


def test_entry_module_exports_the_registry():
    import inbetweening.datasets as entry

    assert entry.load_dataset is load_dataset and entry.register is register and entry.DATASETS is DATASETS
    assert entry.DatasetSpec is DatasetSpec
