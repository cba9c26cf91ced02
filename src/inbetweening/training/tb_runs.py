"""Where a run's TensorBoard events go and what the run is called, so that TensorBoard's run names (a run's path under
``--logdir``) lead with what distinguishes it: one TensorBoard folder for every run of the log folder,
``logs/tensorboard/<label>/<start time>`` (:func:`tensorboard_root`, :func:`run_label`, :func:`run_version`), a run
folder's link to its events (:func:`link_run`, :func:`resumed_run`), the swept keys of a sweep (:func:`swept_keys`)
and the HParams a run shows (:func:`curated_hparams`: the swept keys, then model, data, mask, optimiser essentials and
the training budget)."""
from __future__ import annotations

import os
import re
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

#: The run folder under the TensorBoard root that holds the folder's HParams columns (``tb_logging.update_columns``):
#: not a run of its own.
COLUMNS_RUN = "~columns"
#: Hyper-parameters shown by default after the swept keys (TensorBoard's HParams dashboard shows 5 at first).
SHOWN = ("model/name", "trainer/max_epochs", "data/name", "mask/name", "trainer/max_steps", "model/depth")
#: The curated hyper-parameters after the swept keys: ``(name, config key)``.
ESSENTIALS = (
    ("model/name", "model.name"), ("model/depth", "model.depth"), ("model/heads", "model.heads"),
    ("model/d_model", "model.d_model"), ("model/graph", "model.graph"), ("model/norm", "model.norm"),
    ("model/dropout", "model.dropout"), ("mask/name", "mask.name"), ("data/name", "data.name"),
    ("data/split", "data.split"), ("data/batch_size", "data.batch_size"), ("data/transition_min", "data.transition_min"),
    ("data/transition_max", "data.transition_max"), ("data/max_train_windows", "data.max_train_windows"),
    ("optim/optimizer", "optim.optimizer._target_"), ("optim/lr", "optim.optimizer.lr"),
    ("optim/weight_decay", "optim.optimizer.weight_decay"), ("optim/schedule", "optim.scheduler.decay"),
    ("optim/warmup_steps", "optim.scheduler.warmup_steps"), ("centre", "centre"), ("seed", "seed"),
    ("trainer/max_epochs", "trainer.max_epochs"), ("trainer/max_steps", "trainer.max_steps"),
    ("trainer/max_time", "trainer.max_time"), ("trainer/devices", "trainer.devices"),
)
_NOT_HPARAMS = re.compile(r"^(hydra|paths|ckpt_path|callbacks|logger|experiment|ablation|run_test|optimized_metric)\b")
#: Always HParams columns: what decides whether the test figures are the network's or the blended fill's, and the
#: network's input/output layout.
ALWAYS = ("calibrate", "representation")
#: The config groups and top-level keys every session records in full (so that a key swept by any sweep has a value in
#: every run's row); the paths, the data's generator settings and values interpolated from elsewhere are left out.
RECORDED = ("model", "data", "mask", "optim", "loss", "trainer", "fill", "centre", "representation", "calibrate",
            "calibrate_windows", "seed", "init_from", "init_stats", "init_layers", "compile", "test_keyframes", "foot_lock",
            "self_check", "keyframe_clips", "task_name")
_NOT_RECORDED = re.compile(r"^(data/(path|cache_dir|synthetic|mask|seed|download)|trainer/(_target_|callbacks|logger|"
                           r"plugins|default_root_dir|enable_\w+|log_every_n_steps)|model/_target_|fill/_target_|"
                           r"optim/scheduler/_target_|data/_target_)\b")


def task_overrides() -> list[str]:
    """The command line's ``key=value`` overrides of this Hydra job (``[]`` outside Hydra)."""
    try:
        from hydra.core.hydra_config import HydraConfig

        return [str(o) for o in HydraConfig.get().overrides.task]
    except ValueError:
        return []


_SWEEP = re.compile(r"^(range|choice|glob|interval|tag|shuffle|sort)\(|,")


def swept_keys(argv: Sequence[str] | None = None) -> list[str]:
    """The keys this Hydra multirun sweeps: those the command line gives several values (``model.depth=2,4``,
    ``choice(...)``, ``range(...)``) and those of ``hydra.sweeper.params`` (``ablation=...``).  ``[]`` for a single
    run or outside Hydra."""
    try:
        from hydra.core.hydra_config import HydraConfig
        from hydra.types import RunMode

        hc = HydraConfig.get()
    except ValueError:
        return []
    if hc.mode != RunMode.MULTIRUN:
        return []
    keys = [str(k) for k in (hc.sweeper.get("params") or {})]
    for arg in sys.argv[1:] if argv is None else argv:
        key, eq, val = arg.lstrip("+~").partition("=")
        if eq and not key.startswith("-") and _SWEEP.search(val) and not val.startswith(("[", "{")):
            keys.append(key)
    return list(dict.fromkeys(keys))


def _swept_first(overrides: Sequence[str], swept: Sequence[str]) -> list[str]:
    key = lambda o: o.lstrip("+~").partition("=")[0]  # noqa: E731
    return [o for o in overrides if key(o) in swept] + [o for o in overrides if key(o) not in swept]


def _value(v):
    if isinstance(v, (bool, int, float, str)):
        return v
    if v is None:
        return "none"
    return str(OmegaConf.to_container(v, resolve=True) if OmegaConf.is_config(v) else v)


def curated_hparams(cfg: DictConfig, overrides: Sequence[str] = (), swept: Sequence[str] = ()) -> tuple[dict, list[str]]:
    """``(hparams, shown)``: the curated hyper-parameters (the keys ``overrides`` set, the ``swept`` ones first,
    then :data:`ESSENTIALS` and the non-zero loss weights) and the names that become the columns of a sweep's HParams
    experiment: the swept keys only (every other key is the same in all the jobs of a sweep: a constant column
    says nothing), or, outside a sweep, the keys the command line set."""
    hp: dict = {}
    set_keys = []
    for o in _swept_first(overrides, swept):
        key, _, val = o.lstrip("+~").partition("=")
        if not val or _NOT_HPARAMS.match(key):
            continue
        node = OmegaConf.select(cfg, key)
        name = key.replace(".", "/")
        if OmegaConf.is_dict(node):  # a group choice (model=unet1d): the chosen option's name
            name, node = (f"{name}/name", node.get("name")) if "name" in node else (name, val)
        hp[name] = _value(node)
        set_keys.append((name, key in swept))
    for name, key in ESSENTIALS:
        node = OmegaConf.select(cfg, key, default="__missing__")
        if name not in hp and node != "__missing__":
            hp[name] = _value(node).rsplit(".", 1)[-1] if name == "optim/optimizer" else _value(node)
    for k, v in (cfg.get("loss") or {}).items():
        if v:
            hp.setdefault(f"loss/{k}", _value(v))
    for name, v in _leaves(cfg):  # every other recorded value: a key another sweep varies has this run's value too
        hp.setdefault(name, v)
    shown = [name for name, was_swept in set_keys if was_swept or not swept]
    shown += [k for k in ALWAYS if k in hp]
    return hp, list(dict.fromkeys(shown))


def _leaves(cfg: DictConfig) -> list[tuple[str, object]]:
    """``(name, value)`` of every recorded config value (:data:`RECORDED`), names ``model/depth``, lists as strings."""
    out = []

    def walk(prefix: str, node) -> None:
        if OmegaConf.is_dict(node):
            for k in node:
                try:
                    walk(f"{prefix}/{k}", node[k])
                except Exception:  # an interpolation that does not resolve outside a run: not recorded
                    continue
        elif not _NOT_RECORDED.match(prefix):
            out.append((prefix, _value(node)))

    for key in RECORDED:
        if key in cfg:
            walk(key, cfg[key])
    return out


_LABEL_SKIP = re.compile(r"^(data\.path|data\.cache_dir|threads|compile|trainer\.(log_every_n_steps|enable_\w+|"
                         r"accelerator|devices|num_nodes|precision))\b")
#: The longest run label (a folder name; TensorBoard's run selector wraps long names).
LABEL_MAX = 100


def _short_keys(overrides: Sequence[str]) -> list[str]:
    """``model.norm=layer`` -> ``norm=layer``: each key's last part, where no other key of ``overrides`` ends the
    same (``model.dropout=0.1 data.dropout=0`` keep their full keys)."""
    keys = [o.lstrip("+~").partition("=")[0] for o in overrides]
    last = [k.rsplit(".", 1)[-1] for k in keys]
    return [o.lstrip("+~").replace(k, t, 1) if last.count(t) == 1 else o.lstrip("+~")
            for o, k, t in zip(overrides, keys, last)]


def default_choices() -> dict[str, str]:
    """The primary config's default option per group (``{"data": "synthetic", "mask": "lerp", ...}``: its defaults
    list), read from the running Hydra job's config file; ``{}`` outside Hydra."""
    try:
        import yaml
        from hydra.core.hydra_config import HydraConfig

        hc = HydraConfig.get()
        src = next(s for s in hc.runtime.config_sources if s.provider == "main" and s.schema == "file")
        text = (Path(src.path) / f"{hc.job.config_name}.yaml").read_text()
    except (ValueError, StopIteration, OSError):
        return {}
    out = {}
    for item in (yaml.safe_load(text) or {}).get("defaults", []):
        if isinstance(item, dict):
            for k, v in item.items():
                if isinstance(v, str) and "/" not in str(k) and not str(k).startswith("override"):
                    out[str(k)] = v
    return out


def run_label(cfg: DictConfig, overrides: Sequence[str] = (), swept: Sequence[str] = (),
              defaults: dict[str, str] | None = None) -> str:
    """What distinguishes the run, its TensorBoard name's first part (a path-safe string, at most :data:`LABEL_MAX`
    characters; overrides that do not fit are counted, ``+3 more``):
    in a multirun the swept keys' values, then the keys in brackets (``zero layer (mask norm)``: TensorBoard's image
    cards show about 16 characters of a run's name), else the command line's overrides (sorted; a group set to its
    default option, ``data=synthetic``, is no difference and left out: ``defaults``, default
    :func:`default_choices`), each key shortened to its last part (``model.norm=layer`` -> ``norm=layer``), then the
    model (``zero layer (mask norm) - graph_transformer``;
    ``graph_transformer`` alone for a run of the defaults; no model when the model is among them)."""
    defaults = {} if swept else default_choices() if defaults is None else defaults  # a swept value always counts
    keep = [o for o in overrides if not _NOT_HPARAMS.match(o.lstrip("+~")) and not _LABEL_SKIP.match(o.lstrip("+~"))
            and defaults.get(o.lstrip("+~").partition("=")[0]) != o.partition("=")[2]]  # a group at its default: no
    keep = [o for o in keep if o.lstrip("+~").partition("=")[0] in swept] if swept else sorted(keep)
    keys = {o.lstrip("+~").partition("=")[0] for o in keep}
    model = "" if "model" in keys else str(cfg.model.name)
    parts, room = [], LABEL_MAX - len(model) - 14  # room for " +N more" and " - " + the model
    for i, part in enumerate(_short_keys(keep)):
        if sum(len(p) + 1 for p in parts) + len(part) > room:
            parts.append(f"+{len(keep) - i} more")  # the whole list: .hydra/overrides.yaml and the HParams columns
            break
        parts.append(part)
    head = " ".join(parts)
    if swept and parts and not parts[-1].startswith("+"):  # a sweep's job: the values first (a card shows ~16
        head = " ".join(p.partition("=")[2] for p in parts) + " (" + " ".join(p.partition("=")[0] for p in parts) + ")"
    label = " - ".join(p for p in (head, model) if p)
    return re.sub(r"[^\w.=,@+\-() ]", "_", label.strip())[:LABEL_MAX].strip()


def trial_id(label: str, version: str) -> str:
    """A run's HParams trial id from its folder ``<label>/<version>`` (``version``: its start time,
    ``2026-11-25_19-21-49[_2]``): the start time of day, then the label's values (``zero layer (mask norm) -
    graph_transformer`` or ``depth=2 - graph_transformer`` -> ``zero layer``, ``2``), then the date (and the
    same-second suffix), e.g. ``19:21:49 zero layer (2026-11-25)``.  TensorBoard's table cuts trial ids to about 15
    characters: a re-run differs from the first run in its first 8, the jobs of a sweep started in the same second in
    the values that follow.  Unique as the folder is; a resumed run keeps it."""
    m = re.match(r"^(\d{4}-\d{2}-\d{2})_(\d{2})-(\d{2})-(\d{2})(_\d+)?$", str(version))
    head = str(label).split(" - ")[0]
    values = (" ".join(p.split("=", 1)[1] for p in head.split(" ") if "=" in p) if "=" in head
              else re.sub(r"\s*\([^()]*\)$", "", head))
    if not m:
        return "/".join(p for p in (str(label), str(version)) if p)
    date, hh, mm, ss, k = m.groups()
    return " ".join(p for p in (f"{hh}:{mm}:{ss}", values or str(label), f"({date}{k or ''})") if p)


def tensorboard_root(cfg: DictConfig) -> Path:
    """The folder every run's TensorBoard events go under: ``<paths.log_dir>/tensorboard`` for a run inside the log
    folder (the default Hydra directories), so that ``tensorboard --logdir logs/tensorboard`` names each run by what
    distinguishes it; ``<run dir>/tensorboard`` for a run given a directory of its own elsewhere
    (``hydra.run.dir=/tmp/x``), whose events stay in it."""
    out = Path(cfg.paths.output_dir).resolve()
    log = Path(cfg.paths.log_dir).resolve()
    return log / "tensorboard" if log in out.parents else out / "tensorboard"


def run_version(root: str | Path, label: str, when: float | None = None) -> str:
    """The run's folder under ``<root>/<label>``: its start time (``2026-11-25_19-21-49``), with ``_2``, ``_3``, ...
    where a run of the same label started in the same second, so that a re-run never writes into an earlier run."""
    stamp = time.strftime("%Y-%m-%d_%H-%M-%S", time.localtime(time.time() if when is None else when))
    version, k = stamp, 1
    while (Path(root) / label / version).exists():
        k += 1
        version = f"{stamp}_{k}"
    return version


def resumed_run(cfg: DictConfig) -> Path | None:
    """The TensorBoard run folder a resumed fit (``ckpt_path=<run>/checkpoints/last.ckpt``) continues: the one the
    checkpoint's run directory, or this run directory, logged to (``<run>/tensorboard``: a link to the run's folder,
    or a folder holding it).  ``None`` when not resuming or when there is none or several."""
    if not cfg.get("ckpt_path"):
        return None
    dirs = [Path(cfg.paths.output_dir) / "tensorboard", Path(str(cfg.ckpt_path)).resolve().parent.parent / "tensorboard"]
    for d in dict.fromkeys(dirs):
        if d.is_symlink() and d.resolve().is_dir():
            return d.resolve()
        if d.is_dir():
            runs = sorted({e.parent for e in d.rglob("events.out.tfevents.*") if e.parent.name != COLUMNS_RUN})
            if len(runs) == 1:
                return runs[0]
    return None


def link_run(output_dir: str | Path, run_dir: str | Path) -> None:
    """``<output_dir>/tensorboard``: a relative link to the run's TensorBoard folder when that is elsewhere (the log
    folder's ``tensorboard``), so a run directory still leads to its events and a resume continues them."""
    link, target = Path(output_dir) / "tensorboard", Path(run_dir)
    if link.exists() or link.is_symlink() or Path(output_dir).resolve() in target.resolve().parents:
        return
    try:
        link.parent.mkdir(parents=True, exist_ok=True)
        link.symlink_to(os.path.relpath(target, link.parent), target_is_directory=True)
    except OSError:  # no symbolic links here: the events are still in the log folder's tensorboard
        pass


