"""What a run writes to TensorBoard besides Lightning's scalars, so that a researcher reads it at a glance:

- the scalar names (:func:`tb_scalars`): ``val/l2p@15`` and the ratio ``val/l2p_ratio@15`` (below 1: better than
  interpolation) in the model's groups, interpolation's value on the same windows in a group of its own that
  TensorBoard lists last (``~interpolation/val/l2p@15``, :data:`BASELINE`);
- where a run's events go (:func:`tensorboard_root`, :func:`run_label`, :func:`run_version`): one TensorBoard
  folder for every run of the log folder, ``logs/tensorboard/<what distinguishes the run>/<start time>``, so that
  TensorBoard's run names (a run's path under ``--logdir``) lead with the swept values;
- :class:`RunLogger`: Lightning's TensorBoard logger with ``train/epoch`` and ``train/lr`` in the ``train`` group,
  the test scalars at the last validation's step, and an HParams session (:meth:`RunLogger.start_session`) written
  when fitting starts (running or interrupted runs appear) whose trial id is the run's path, unique per run;
- which run says the HParams dashboard's columns: only the jobs of a sweep write an HParams *experiment* (see
  :class:`HParamsSession`);
- :func:`curated_hparams`: the swept keys, then model, data, mask, optimiser essentials and the training budget;
- :func:`custom_scalars_layout`: per metric and length one chart of the ratio to interpolation (the runs of a sweep
  as its lines), one of the model's values, the training curves each in a chart of its own;
- :class:`TrainStats`: windows/s, epoch time and gradient norm under ``train/``.
"""
from __future__ import annotations

import os
import re
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import lightning as L
import torch
from lightning.pytorch.loggers import TensorBoardLogger
from omegaconf import DictConfig, OmegaConf

METRICS = ("l2p", "l2q", "npss")
#: The group of the interpolation baseline's scalars (``~interpolation/val/l2p@15``): TensorBoard sorts its scalar
#: groups by character code, so ``~`` lists it after the model's ``test``, ``train`` and ``val``.
BASELINE = "~interpolation"
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


def tb_scalars(stage: str, res: Mapping[str, float], interp: Mapping[str, float], pos_rmse: float) -> dict[str, float]:
    """``{stage}/l2p@15`` ..., ``{stage}/l2p_mean``, ``{stage}/l2p_ratio@15`` ... (model / interpolation, where
    interpolation's is not 0), ``{stage}/pos_rmse_cm`` and the baseline ``~interpolation/{stage}/l2p@15`` ...
    (:data:`BASELINE`)."""
    logs = {f"{stage}/{k}": float(v) for k, v in res.items()}
    l2p = [v for k, v in res.items() if k.startswith("l2p@")]
    if l2p:
        logs[f"{stage}/l2p_mean"] = float(sum(l2p) / len(l2p))
    for k, v in interp.items():
        if k in res:
            logs[f"{BASELINE}/{stage}/{k}"] = float(v)
            if v:
                name, n = k.split("@")
                logs[f"{stage}/{name}_ratio@{n}"] = float(res[k]) / float(v)
    logs[f"{stage}/pos_rmse_cm"] = float(pos_rmse)
    return logs


def hparams_metrics(test_lengths: Sequence[int], val_lengths: Sequence[int]) -> list[str]:
    """Metric columns of the HParams dashboard, in order (it shows the first 5 by default): best validation
    L2P, the test L2P ratios to interpolation, then the test L2P values, the validation ratios and L2Q/NPSS."""
    return ["val/l2p_mean_best", *[f"test/l2p_ratio@{n}" for n in test_lengths], *[f"test/l2p@{n}" for n in test_lengths],
            *[f"val/l2p_ratio@{n}" for n in val_lengths], "test/l2p_mean", *[f"test/l2q@{n}" for n in test_lengths],
            *[f"test/npss@{n}" for n in test_lengths]]


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
    shown = [name for name, was_swept in set_keys if was_swept or not swept]
    return hp, list(dict.fromkeys(shown))


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


def run_label(cfg: DictConfig, overrides: Sequence[str] = (), swept: Sequence[str] = ()) -> str:
    """What distinguishes the run, its TensorBoard name's first part (a path-safe string, at most :data:`LABEL_MAX`
    characters; overrides that do not fit are counted, ``+3 more``):
    in a multirun the swept keys' values, else the command line's overrides (sorted), each key shortened to its last
    part (``model.norm=layer`` -> ``norm=layer``), then the model (``mask=zero norm=layer - graph_transformer``;
    ``graph_transformer`` alone for a run of the defaults; no model when the model is among them)."""
    keep = [o for o in overrides if not _NOT_HPARAMS.match(o.lstrip("+~")) and not _LABEL_SKIP.match(o.lstrip("+~"))]
    keep = [o for o in keep if o.lstrip("+~").partition("=")[0] in swept] if swept else sorted(keep)
    keys = {o.lstrip("+~").partition("=")[0] for o in keep}
    model = "" if "model" in keys else str(cfg.model.name)
    parts, room = [], LABEL_MAX - len(model) - 10
    for i, part in enumerate(_short_keys(keep)):
        if sum(len(p) + 1 for p in parts) + len(part) > room:
            parts.append(f"+{len(keep) - i} more")  # the whole list: .hydra/overrides.yaml and the HParams columns
            break
        parts.append(part)
    label = " - ".join(p for p in (" ".join(parts), model) if p)
    return re.sub(r"[^\w.=,@+\- ]", "_", label.strip())[:LABEL_MAX].strip()


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
            runs = sorted({e.parent for e in d.rglob("events.out.tfevents.*")})
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


def custom_scalars_layout(val_lengths: Sequence[int], test_lengths: Sequence[int]) -> dict:
    """The Custom Scalars dashboard (TensorBoard colours its lines by run only, so each chart holds one quantity and
    a sweep's runs are its lines): per metric and validation length the ratio to interpolation (below 1: the model
    beats it; interpolation is the line at 1), then the model's values, the training curves (``train/loss`` and
    ``val/loss`` in charts of their own) and the interpolation baseline by itself."""
    ratio = {f"{m.upper()}@{n} / interpolation": ["Multiline", [rf"^val/{m}_ratio@{n}$"]]
             for m in METRICS for n in val_lengths}
    model = {f"L2P@{n}": ["Multiline", [rf"^val/l2p@{n}$"]] for n in val_lengths}
    model["L2P, mean of the lengths"] = ["Multiline", [r"^val/l2p_mean$"]]
    model["position RMSE (cm)"] = ["Multiline", [r"^val/pos_rmse_cm$"]]
    train = {"training loss": ["Multiline", [r"^train/loss$"]], "validation loss": ["Multiline", [r"^val/loss$"]],
             "learning rate": ["Multiline", [r"^train/lr$"]],
             "throughput (windows/s)": ["Multiline", [r"^train/windows_per_s$"]],
             "gradient norm (before clipping)": ["Multiline", [r"^train/grad_norm$"]]}
    base = {f"interpolation L2P@{n}": ["Multiline", [rf"^{re.escape(BASELINE)}/val/l2p@{n}$"]] for n in val_lengths}
    return {"1 val: model / interpolation (< 1: better)": ratio, "2 val: model": model, "3 train": train,
            "4 interpolation baseline": base}


class RunLogger(TensorBoardLogger):
    """:class:`~lightning.pytorch.loggers.TensorBoardLogger` whose ``epoch`` and learning rate go to the
    ``train`` group (``train/epoch``, ``train/lr``), whose test scalars are written at the step of the last validation
    (where the validation curves end, not alone one step further), and which writes an HParams session of the
    run's own, its trial id the run's path (``<label>/<start time>``): a re-run of the same command is a row of its
    own, never averaged with the earlier one."""

    RENAME = {"epoch": "train/epoch", "lr": "train/lr"}

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._session_started = False
        self._reopened = None  # the event file written after Lightning closed the SummaryWriter (see _write)
        self.last_val_step: int | None = None

    @property
    def trial_id(self) -> str:
        """The run's HParams trial id: its path under the TensorBoard folder (``<label>/<start time>``)."""
        return "/".join(str(p) for p in (self.name, self.version) if p not in (None, ""))

    def log_metrics(self, metrics: Mapping[str, float], step: int | None = None) -> None:
        renamed = {self.RENAME.get(k, "train/lr" if k.startswith("lr-") else k): v for k, v in metrics.items()}
        if any(k.startswith("val/") for k in renamed) and step is not None:
            self.last_val_step = int(step)
        elif renamed and self.last_val_step is not None and all(
                k.startswith(("test/", f"{BASELINE}/test/")) for k in renamed):
            step = self.last_val_step
        super().log_metrics(renamed, step)

    def _write(self, summary) -> None:
        """Write a summary (the HParams plugin's) into this run's event file: the SummaryWriter's own (its
        ``file_writer``); once Lightning has closed the writer (``finalize`` at the end of a fit) and no scalar has
        reopened it, a new event file in the same folder, as the SummaryWriter itself would open."""
        writer = self.experiment.file_writer
        if writer is None:
            if self._reopened is None:
                from torch.utils.tensorboard.writer import FileWriter

                self._reopened = FileWriter(self.experiment.get_logdir())
            writer = self._reopened
        writer.add_summary(summary)
        writer.flush()

    def finalize(self, status: str) -> None:
        super().finalize(status)
        if self._reopened is not None:
            self._reopened.close()
            self._reopened = None

    def start_session(self, hparams: Mapping, shown: Sequence[str], metrics: Sequence[str], layout: dict | None = None,
                      experiment: bool = True) -> None:
        """Write this run's session start (its ``hparams`` values, trial id :attr:`trial_id`), the Custom Scalars
        ``layout`` and, with ``experiment``, the HParams experiment (the dashboard's columns: the names of ``shown``,
        every name of ``hparams`` when ``shown`` holds none of them; the ``metrics`` columns in order).  Once per
        logger."""
        if self._session_started or self.experiment is None:
            return
        from tensorboard.plugins.hparams import summary_v2 as hp_summary

        if experiment:
            self._write(self._experiment_summary(hparams, shown, metrics))
        self._write(hp_summary.hparams_pb(dict(hparams), trial_id=self.trial_id or None))
        if layout:
            self.experiment.add_custom_scalars(layout)
        self._session_started = True

    @staticmethod
    def _experiment_summary(hparams: Mapping, shown: Sequence[str], metrics: Sequence[str]):
        """The HParams experiment summary: typed columns for the names of ``shown`` (in ``hparams``' order, marked
        ``differs``), or for every name of ``hparams`` when ``shown`` holds none.  The dashboard shows the first 5
        columns (``differs`` first), so a constant one would take the place of a key that varies."""
        from tensorboard.plugins.hparams import summary_v2 as hp_summary

        columns = [k for k in hparams if k in shown] or list(hparams)
        exp = hp_summary.hparams_config_pb([hp_summary.HParam(k) for k in columns],
                                           [hp_summary.Metric(m) for m in metrics])
        config = exp.value[0]
        from tensorboard.plugins.hparams import api_pb2, metadata

        data = metadata.parse_experiment_plugin_data(config.metadata.plugin_data.content)
        for info in data.hparam_infos:
            info.differs = info.name in shown  # the dashboard sorts these first
            v = hparams[info.name]  # typed columns: numbers get an interval axis in the parallel coordinates
            info.type = (api_pb2.DATA_TYPE_BOOL if isinstance(v, bool) else api_pb2.DATA_TYPE_FLOAT64
                         if isinstance(v, (int, float)) else api_pb2.DATA_TYPE_STRING)
        config.metadata.CopyFrom(metadata.create_summary_metadata(metadata.plugin_data_pb2.HParamsPluginData(
            experiment=data, version=metadata.PLUGIN_DATA_VERSION)))
        return exp

    def end_session(self, status: str = "success") -> None:
        """Mark this run's HParams session ended (``success`` | ``failure``)."""
        if not self._session_started:
            return
        from tensorboard.plugins.hparams import api_pb2, metadata
        from tensorboard.plugins.hparams.summary_v2 import _summary_pb

        info = metadata.plugin_data_pb2.SessionEndInfo(
            status=api_pb2.STATUS_SUCCESS if status == "success" else api_pb2.STATUS_FAILURE, end_time_secs=time.time())
        self._write(_summary_pb(metadata.SESSION_END_INFO_TAG,
                                metadata.plugin_data_pb2.HParamsPluginData(session_end_info=info)))
        self.experiment.flush()


class HParamsSession(L.Callback):
    """Starts each :class:`RunLogger`'s HParams session (and Custom Scalars layout) when fitting starts, and
    marks it failed if fitting raises.  ``hparams``, ``shown``: :func:`curated_hparams`.

    ``experiment`` (a sweep's job): also write the HParams experiment, the dashboard's columns with the swept keys
    marked to be shown first and the curated metric columns.  TensorBoard's HParams plugin (2.21,
    ``backend_context._find_experiment_tag``) does not merge experiments: it serves the first one it finds, in the
    order it happens to list the runs.  So a single run writes none: in a logdir that holds a sweep, the sweep's is
    the one served (its swept keys stay the default columns); in a logdir of single runs only, the plugin builds
    the columns from every run's session (the hparams whose values differ between the runs first)."""

    def __init__(self, hparams: Mapping, shown: Sequence[str], val_lengths: Sequence[int], test_lengths: Sequence[int],
                 end_at_fit_end: bool = False, experiment: bool = True):
        self.hparams, self.shown, self.end_at_fit_end = dict(hparams), list(shown), end_at_fit_end
        self.val_lengths, self.test_lengths = list(val_lengths), list(test_lengths)
        self.experiment = bool(experiment)

    def start(self, trainer: L.Trainer) -> None:
        if not trainer.is_global_zero:
            return
        for lg in trainer.loggers:
            if isinstance(lg, RunLogger):
                lg.start_session(self.hparams, self.shown, hparams_metrics(self.test_lengths, self.val_lengths),
                                 custom_scalars_layout(self.val_lengths, self.test_lengths), self.experiment)

    def on_fit_start(self, trainer, pl_module) -> None:
        self.start(trainer)

    def on_fit_end(self, trainer, pl_module) -> None:
        if self.end_at_fit_end and trainer.is_global_zero:  # run_test=false: the run ends with its fit
            for lg in trainer.loggers:
                if isinstance(lg, RunLogger):
                    lg.end_session("success")

    def on_exception(self, trainer, pl_module, exception: BaseException) -> None:
        for lg in trainer.loggers:
            if isinstance(lg, RunLogger) and trainer.is_global_zero:
                lg.end_session("failure")


class TrainStats(L.Callback):
    """``train/windows_per_s`` (training windows per second of step time, every step), ``train/epoch_time_s``
    and ``train/grad_norm`` (total L2 norm of the gradients before clipping).  Reads clocks only: no RNG."""

    def __init__(self):
        self._t0 = self._epoch_t0 = 0.0

    def on_train_epoch_start(self, trainer, pl_module) -> None:
        self._epoch_t0 = time.perf_counter()

    def on_train_batch_start(self, trainer, pl_module, batch, batch_idx) -> None:
        self._t0 = time.perf_counter()

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx) -> None:
        dt = time.perf_counter() - self._t0
        n = batch["q"].shape[0] if isinstance(batch, dict) and "q" in batch else 0
        if dt > 0 and n:
            pl_module.log("train/windows_per_s", n / dt, on_step=True, on_epoch=False, batch_size=n)

    def on_train_epoch_end(self, trainer, pl_module) -> None:
        pl_module.log("train/epoch_time_s", time.perf_counter() - self._epoch_t0, on_step=False, on_epoch=True)

    def on_before_optimizer_step(self, trainer, pl_module, optimizer) -> None:
        grads = [p.grad.detach().norm() for p in pl_module.parameters() if p.grad is not None]
        if grads:
            pl_module.log("train/grad_norm", torch.stack(grads).norm(), on_step=True, on_epoch=False)
