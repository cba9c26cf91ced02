"""Every dataset is one :class:`DatasetSpec` in the :data:`DATASETS` registry.

A spec holds everything :func:`inbetweening.data.datasets.load_dataset` needs: the file pattern, its named
split rules (file name -> ``"train"``/``"test"``/``None``; ``"standard"`` is the default, ``data.split``
picks another), the root-local forward axis, where the files are found
(environment variable, the config's default path, a hint for a missing path, an optional download), an
optional static root joint to fold into its child, the left/right mirror map, the frame rate, and the
reader (the BVH reader by default; a non-BVH source plugs in its own).  A new BVH dataset is one
:func:`register` call (or one entry below) plus one ``conf/data/<name>.yaml``.

* ``lafan1``       - Ubisoft LAFAN1, 77 BVH files ``<name>_subjectN.bvh`` (folder or ``lafan1.zip``);
                     train = subject1-4, test = subject5; forward = root local +Y.
* ``bandai_namco`` - Bandai-Namco-Research-Motiondataset-1/-2 (folder or zip).  The static
                     ``joint_Root`` is folded into ``Hips``, which becomes the root; test = takes whose
                     3-digit take number is divisible by 10, train = the rest (split ``standard``), or
                     test = every take of the contents ``run`` and ``wave-both-hands``, train = the other
                     contents (split ``content``: motions never seen in training), or one content held out
                     (split ``holdout-<content>``, leave-one-content-out); forward = root local +Z
                     (measured on walk clips, see docs/datasets.md).
* ``synthetic``    - procedurally generated LAFAN-format BVH files (see :mod:`inbetweening.data.synthetic`),
                     read back through the same BVH reader; test = subject5; forward = root local +Z.
"""
from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from inbetweening.data.clips import Clip, read_bvh_clips
from inbetweening.data.errors import DatasetError
from inbetweening.data.lafan1 import download_lafan1
from inbetweening.data.mirror import MirrorMap
from inbetweening.data.synthetic import generate_dataset
from inbetweening.geometry.skeleton import Skeleton

SplitRule = Callable[[str], "str | None"]
# reader(spec, path) -> (file name, clip, skeleton, frames per second or None) per file, sorted by name
Reader = Callable[["DatasetSpec", Path], Iterable[tuple[str, Clip, Skeleton, "float | None"]]]

DEFAULT_SPLIT = "standard"

__all__ = [
    "BN_CONTENTS", "BN_FOLDS", "BN_TEST_CONTENTS", "DATASETS", "DEFAULT_SPLIT", "DatasetSpec", "bandai_namco_content",
    "bandai_namco_content_split", "bandai_namco_fold_splits", "bandai_namco_split", "get_spec", "lafan_split", "register",
]


@dataclass(frozen=True)
class DatasetSpec:
    """Everything that makes a dataset; see the module docstring.

    ``splits`` maps split names to split rules; it must hold :data:`DEFAULT_SPLIT` (``"standard"``), the split
    used unless another is asked for (``load_dataset(..., split=...)``, ``data.split=...``).  A single rule
    is the spec's only split, ``"standard"``.  :attr:`split` is the standard rule.

    ``mirror`` is a tuple of ``(left, right)`` joint names of the *loaded* skeleton (after root folding), or
    ``None`` to derive it from the names' side markers (``LeftArm``/``RightArm``, ``Hand_L``/``Hand_R``); either
    way it is validated against the skeleton on load (:mod:`inbetweening.data.mirror`) and handed out as
    ``MotionData.mirror``.  Declare explicit pairs (e.g. with :func:`~inbetweening.data.mirror.side_pairs`) only
    for names no side marker covers: an explicit map must fit every skeleton the spec is used with.

    ``fps`` is the dataset's nominal frame rate: the files' own rate wins (a mismatch warns), and a reader
    that knows none gets ``fps``.  ``generate(folder, **options)`` makes a generated dataset's files (no path
    is read then).  ``default_path`` is the config's default location relative to the repository root
    (``conf/data/<name>.yaml``); ``path_hint`` says where to get the files when the path is missing.

    ``feet`` names the foot/toe joints of the loaded skeleton scored for foot skating by ``protocol=keyframes``
    (:mod:`inbetweening.evaluation.keyframes`; empty: no skating figures); a foot joint is in contact when its
    height (Y up, the data's length unit) is below ``contact_height`` and its speed (units per second) below
    ``contact_speed``.
    """

    name: str
    splits: SplitRule | Mapping[str, SplitRule] = field(hash=False)
    forward_axis: tuple[float, float, float]
    pattern: str = "*.bvh"
    env_var: str | None = None
    default_path: str | None = None
    path_hint: str = ""
    fold_root: str | None = None
    mirror: MirrorMap | None = None
    fps: float = 30.0
    reader: Reader = read_bvh_clips
    download: Callable[[Path], Path] | None = None
    generate: Callable[..., Path] | None = None
    feet: tuple[str, ...] = ()
    contact_height: float = 0.0
    contact_speed: float = 0.0

    def __post_init__(self):
        if len(self.forward_axis) != 3:
            raise ValueError(f"DatasetSpec {self.name!r}: forward_axis must have 3 components, got {self.forward_axis!r}")
        object.__setattr__(self, "forward_axis", tuple(float(a) for a in self.forward_axis))
        object.__setattr__(self, "feet", tuple(self.feet))
        if self.feet and not (self.contact_height > 0 and self.contact_speed > 0):
            raise ValueError(f"DatasetSpec {self.name!r}: feet need contact_height > 0 and contact_speed > 0, got "
                             f"{self.contact_height!r} and {self.contact_speed!r}")
        splits = {DEFAULT_SPLIT: self.splits} if callable(self.splits) else dict(self.splits)
        if DEFAULT_SPLIT not in splits or not all(callable(r) for r in splits.values()):
            raise ValueError(f"DatasetSpec {self.name!r}: splits must map names to split rules and include "
                             f"{DEFAULT_SPLIT!r}, got {sorted(splits)}")
        object.__setattr__(self, "splits", splits)

    @property
    def split(self) -> SplitRule:
        """The standard split's rule."""
        return self.splits[DEFAULT_SPLIT]

    def split_rule(self, split: str) -> SplitRule:
        """The rule of the split called ``split``; :class:`DatasetError` listing the spec's splits otherwise."""
        if split not in self.splits:
            raise DatasetError(f"dataset {self.name!r} has no split {split!r}; its splits are {self.split_names()}")
        return self.splits[split]

    def split_names(self) -> str:
        """The split names for a message: ``['standard', 'content']``, then ``holdout-<content> for the contents a, b,
        ...`` where the spec has leave-one-content-out splits."""
        plain = [n for n in self.splits if not n.startswith(("holdout-", "fold-"))]
        held = [n[len("holdout-"):] for n in self.splits if n.startswith("holdout-")]
        folds = [n for n in self.splits if n.startswith("fold-")]
        return (f"{plain}" + (f" and holdout-<content> for the contents {', '.join(held)}" if held else "")
                + (f" and the folds {', '.join(folds)}" if folds else ""))

    def reads(self, fname: str) -> bool:
        """Whether some split of the spec uses the file ``fname`` (the reader skips the others unparsed)."""
        return any(rule(fname) is not None for rule in self.splits.values())


# ------------------------------------------------------------------------------------------
# Split rules
# ------------------------------------------------------------------------------------------
_LAFAN_RE = re.compile(r"^(?P<seq>.+)_(?P<subject>subject\d+)\.bvh$", re.IGNORECASE)
_BN_RE = re.compile(r"^dataset-(?P<ds>[12])_(?P<content>.+?)_(?P<style>[^_]+)_(?P<take>\d+)\.bvh$", re.IGNORECASE)


def lafan_split(fname: str, train_subjects=("subject1", "subject2", "subject3", "subject4"), test_subjects=("subject5",)):
    """``<seq>_subjectN.bvh``: subject1-4 train, subject5 test; ``None`` for other names."""
    m = _LAFAN_RE.match(fname)
    if not m:
        return None
    subj = m.group("subject").lower()
    return "train" if subj in train_subjects else "test" if subj in test_subjects else None


def bandai_namco_split(fname: str):
    """``dataset-N_<content>_<style>_<take>.bvh``: test when the take number is divisible by 10."""
    m = _BN_RE.match(fname)
    if not m:
        return None
    return "test" if int(m.group("take")) % 10 == 0 else "train"


BN_TEST_CONTENTS = ("run", "wave-both-hands")  # Bandai-Namco-2 contents held out whole by the content split
# Bandai-Namco-2's ten contents; split ``holdout-<content>`` holds out that one (the leave-one-content-out check)
BN_CONTENTS = ("raise-up-both-hands", "raise-up-left-hand", "raise-up-right-hand", "run", "walk", "walk-turn-left",
               "walk-turn-right", "wave-both-hands", "wave-left-hand", "wave-right-hand")


def bandai_namco_content(name: str) -> str | None:
    """The content of a Bandai-Namco file or clip name ``dataset-N_<content>_<style>_<take>[.bvh]`` (lower case);
    ``None`` for other names."""
    m = _BN_RE.match(name if name.lower().endswith(".bvh") else f"{name}.bvh")
    return m.group("content").lower() if m else None


def bandai_namco_content_split(fname: str, test_contents=BN_TEST_CONTENTS):
    """``dataset-N_<content>_<style>_<take>.bvh``: test when the content is one of ``test_contents`` (every take
    and style of it), train otherwise: the test motions are never seen in training or validation."""
    content = bandai_namco_content(fname) if fname.lower().endswith(".bvh") else None
    if content is None:
        return None
    return "test" if content in test_contents else "train"


def bandai_namco_holdout_splits() -> dict[str, SplitRule]:
    """``holdout-<content>`` for each of :data:`BN_CONTENTS`: test = every take of that one content, train = the nine
    others (the leave-one-content-out check of motions never seen)."""
    def rule(content: str) -> SplitRule:
        return lambda fname: bandai_namco_content_split(fname, (content,))
    return {f"holdout-{c}": rule(c) for c in BN_CONTENTS}


# The generalisation folds: five pairs of contents, each held out whole by split ``fold-<i>``, so every content is a
# test content once.  Fold 1 is the content split; folds 2-4 pair a walk with an arm gesture; fold 5 holds the two
# one-handed gestures left, each with its mirror image in training (benchmarks/folds.sh, RESULTS.md section 3.3).
BN_FOLDS = (("run", "wave-both-hands"), ("walk", "raise-up-both-hands"), ("walk-turn-left", "wave-left-hand"),
            ("walk-turn-right", "raise-up-right-hand"), ("raise-up-left-hand", "wave-right-hand"))


def bandai_namco_fold_splits() -> dict[str, SplitRule]:
    """``fold-<i>`` (1-5) for each pair of :data:`BN_FOLDS`: test = every take of the two contents, train = the eight
    others."""
    def rule(contents: tuple[str, ...]) -> SplitRule:
        return lambda fname: bandai_namco_content_split(fname, contents)
    return {f"fold-{i}": rule(pair) for i, pair in enumerate(BN_FOLDS, 1)}


# ------------------------------------------------------------------------------------------
# The registry
# ------------------------------------------------------------------------------------------
DATASETS: dict[str, DatasetSpec] = {}


def register(spec: DatasetSpec, replace: bool = False) -> DatasetSpec:
    """Add ``spec`` to :data:`DATASETS` under its name (``replace=True`` to overwrite an existing one)."""
    if spec.name in DATASETS and not replace:
        raise ValueError(f"dataset {spec.name!r} is already registered")
    DATASETS[spec.name] = spec
    return spec


def get_spec(name: str) -> DatasetSpec:
    """The registered spec called ``name``; :class:`DatasetError` listing the known names otherwise."""
    if name not in DATASETS:
        raise DatasetError(f"unknown dataset {name!r}; choose one of {sorted(DATASETS)}")
    return DATASETS[name]


# Foot contact (protocol=keyframes foot skating), cm and cm/s, chosen on the Bandai-Namco-2 test clips: planted
# feet sit at 11.7-12.4 cm (Foot_*, 5th-95th percentile of pairs slower than 15 cm/s) and toes at 4.3-5.7 cm
# (Toes_*) above the floor (y = 0); height < 15 cm and speed < 30 cm/s flags 75 % (feet) / 78 % (toes) of the frame
# pairs, and for the toes exactly the pairs a 8 cm height limit flags (the speed limit already excludes the swing).
# LAFAN1 (cm, 30 fps) and the synthetic data use the same values (LAFAN1 is not on this machine to check them).
CONTACT = {"contact_height": 15.0, "contact_speed": 30.0}

# Mirror maps: the built-ins derive theirs from the loaded joint names (mirror=None), so a LAFAN-format folder
# with another skeleton still loads (it is refused later, e.g. by a checkpoint of another skeleton).  The maps
# this gives for the real skeletons are pinned in tests/test_mirror.py.
register(DatasetSpec(
    "lafan1", lafan_split, (0.0, 1.0, 0.0), env_var="LAFAN1_PATH", default_path="data/lafan1.zip",
    path_hint="download lafan1.zip from the ubisoft-laforge-animation-dataset repository and pass its path "
    "(or the folder of extracted .bvh files) as data.path=... or $LAFAN1_PATH",
    download=download_lafan1, feet=("LeftFoot", "LeftToe", "RightFoot", "RightToe"), **CONTACT,
))  # fmt: skip
register(DatasetSpec(
    "bandai_namco", {DEFAULT_SPLIT: bandai_namco_split, "content": bandai_namco_content_split,
                     **bandai_namco_holdout_splits(), **bandai_namco_fold_splits()}, (0.0, 0.0, 1.0),
    env_var="BANDAI_NAMCO_PATH",
    default_path="../shared/datasets/bandai-namco-2.zip",
    path_hint="pass the Bandai-Namco-Research-Motiondataset zip or its data/ folder as data.path=...",
    fold_root="joint_Root", feet=("Foot_L", "Toes_L", "Foot_R", "Toes_R"), **CONTACT,
))  # fmt: skip
register(DatasetSpec("synthetic", lafan_split, (0.0, 0.0, 1.0), generate=generate_dataset,
                     feet=("LeftFoot", "LeftToe", "RightFoot", "RightToe"), **CONTACT))
