"""What a run writes to TensorBoard besides Lightning's scalars, so that a researcher reads it at a glance:

- the scalar names (:func:`tb_scalars`): ``val/l2p@15`` and the ratio ``val/l2p_ratio@15`` (below 1: better than
  interpolation) in the model's groups, interpolation's value on the same windows in a group of its own that
  TensorBoard lists last (``~interpolation/val/l2p@15``, :data:`BASELINE`);
- where a run's events go and what it is called: :mod:`inbetweening.training.tb_runs`;
- :class:`RunLogger`: Lightning's TensorBoard logger with ``train/epoch`` and ``train/lr`` in the ``train`` group,
  the test scalars at the last validation's step, and an HParams session (:meth:`RunLogger.start_session`) written
  when fitting starts (running or interrupted runs appear) whose trial id is the run's path, unique per run;
- the HParams dashboard's columns: one experiment for the whole TensorBoard folder, in a run of its own
  (:data:`COLUMNS_RUN`, :func:`update_columns`), which every run adds its swept (or set) keys to;
- :func:`custom_scalars_layout`: per metric and length one chart of the ratio to interpolation (the runs of a sweep
  as its lines), one of the model's values, the training curves each in a chart of its own;
- :class:`TrainStats`: windows/s, epoch time and gradient norm under ``train/``.
"""
from __future__ import annotations

import fcntl
import json
import re
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import lightning as L
import torch
from lightning.pytorch.loggers import TensorBoardLogger

from inbetweening.training.tb_runs import COLUMNS_RUN, trial_id

METRICS = ("l2p", "l2q", "npss")
#: The group of the interpolation baseline's scalars (``~interpolation/val/l2p@15``): TensorBoard sorts its scalar
#: groups by character code, so ``~`` lists it after the model's ``test``, ``train`` and ``val``.
BASELINE = "~interpolation"


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
    if interp:  # the line at 1 that every ratio chart of Custom Scalars draws: interpolation itself
        logs[f"{BASELINE}/{stage}/ratio"] = 1.0
    return logs




def _column_type(v) -> str:
    return "bool" if isinstance(v, bool) else "float" if isinstance(v, (int, float)) else "string"


def update_columns(root: str | Path, hparams: Mapping, shown: Sequence[str], metrics: Sequence[str],
                   trial: str | None = None) -> bool:
    """Add ``shown`` (hparam names, typed by their values in ``hparams``) and ``metrics`` to the HParams columns of
    the TensorBoard folder ``root``: one experiment in the run :data:`COLUMNS_RUN`, rewritten (its state in
    ``columns.json``, under a file lock: a sweep's jobs update it at once) whenever a column is new.  TensorBoard's
    HParams plugin serves the first experiment it finds and never merges them (``backend_context.
    _find_experiment_tag``, 2.21), so the folder holds exactly one: every sweep's keys and every single run's are its
    columns, and every run's session records every config value (a row shows its value of a key another sweep
    varied).  Returns whether it was rewritten (a running TensorBoard shows new columns after a restart)."""
    from tensorboard.plugins.hparams import api_pb2, metadata
    from tensorboard.plugins.hparams import summary_v2 as hp_summary
    from torch.utils.tensorboard.writer import FileWriter

    folder = Path(root) / COLUMNS_RUN
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / ".lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        state_file = folder / "columns.json"
        state = json.loads(state_file.read_text()) if state_file.exists() else {"hparams": {}, "metrics": []}
        runs = state.setdefault("runs", {})  # every run's values (a column added later knows earlier runs' too)
        before = json.dumps(state, sort_keys=True)
        for k in shown:
            if k in hparams:
                state["hparams"].setdefault(k, _column_type(hparams[k]))
        runs[str(trial or len(runs))] = {k: str(v) for k, v in hparams.items()}
        state["metrics"] += [m for m in metrics if m not in state["metrics"]]
        events = sorted(folder.glob("events.out.tfevents.*"))
        if json.dumps(state, sort_keys=True) == before and events:
            return False
        exp = hp_summary.hparams_config_pb([hp_summary.HParam(k) for k in state["hparams"]],
                                           [hp_summary.Metric(m) for m in state["metrics"]])
        config = exp.value[0]
        data = metadata.parse_experiment_plugin_data(config.metadata.plugin_data.content)
        kinds = {"bool": api_pb2.DATA_TYPE_BOOL, "float": api_pb2.DATA_TYPE_FLOAT64, "string": api_pb2.DATA_TYPE_STRING}
        for info in data.hparam_infos:
            info.differs = len({r.get(info.name) for r in runs.values()}) > 1  # the dashboard shows these first
            info.type = kinds[state["hparams"][info.name]]  # numbers get an interval axis in the parallel coordinates
        config.metadata.CopyFrom(metadata.create_summary_metadata(metadata.plugin_data_pb2.HParamsPluginData(
            experiment=data, version=metadata.PLUGIN_DATA_VERSION)))
        for old in events:
            old.unlink()
        writer = FileWriter(str(folder))
        writer.add_summary(exp)
        writer.close()
        tmp = state_file.with_suffix(".tmp")
        tmp.write_text(json.dumps(state, indent=1))
        tmp.replace(state_file)
        return True


def hparams_metrics(test_lengths: Sequence[int], val_lengths: Sequence[int]) -> list[str]:
    """Metric columns of the HParams dashboard, in order: best validation L2P (the network: the blend is fitted
    after training), the test L2P ratios to interpolation of the fill (``test/``: the calibrated blend, what the tools
    deliver) and of the network alone (``test_network/``), then the test L2P values, the validation ratios and
    L2Q/NPSS."""
    return ["val/l2p_mean_best", *[f"test/l2p_ratio@{n}" for n in test_lengths],
            *[f"test_network/l2p_ratio@{n}" for n in test_lengths], *[f"test/l2p@{n}" for n in test_lengths],
            *[f"val/l2p_ratio@{n}" for n in val_lengths], "test/l2p_mean", *[f"test/l2q@{n}" for n in test_lengths],
            *[f"test/npss@{n}" for n in test_lengths]]


def custom_scalars_layout(val_lengths: Sequence[int], test_lengths: Sequence[int]) -> dict:
    """The Custom Scalars dashboard (TensorBoard colours its lines by run only, so each chart holds one quantity and
    a sweep's runs are its lines): per metric and validation length the ratio to interpolation (below 1: the model
    beats it; interpolation is the line at 1, ``~interpolation/val/ratio``), the test ratios of the blended fill and
    of the network alone per length (points at the last validation's step; the line at 1 too), then the model's
    values, the training curves (``train/loss`` and ``val/loss`` in charts of their own) and the interpolation baseline
    by itself."""
    one = rf"^{re.escape(BASELINE)}/%s/ratio$"  # interpolation: the constant 1 in every ratio chart
    ratio = {f"{m.upper()}@{n} / interpolation": ["Multiline", [rf"^val/{m}_ratio@{n}$", one % "val"]]
             for m in METRICS for n in val_lengths}
    test = {f"L2P@{n} / interpolation: the fill (test/), the network alone (test_network/)":
            ["Multiline", [rf"^test/l2p_ratio@{n}$", rf"^test_network/l2p_ratio@{n}$", one % "test"]]
            for n in test_lengths}
    model = {f"L2P@{n}": ["Multiline", [rf"^val/l2p@{n}$"]] for n in val_lengths}
    model["L2P, mean of the lengths"] = ["Multiline", [r"^val/l2p_mean$"]]
    model["position RMSE (cm)"] = ["Multiline", [r"^val/pos_rmse_cm$"]]
    train = {"training loss": ["Multiline", [r"^train/loss$"]], "validation loss": ["Multiline", [r"^val/loss$"]],
             "learning rate": ["Multiline", [r"^train/lr$"]],
             "throughput (windows/s)": ["Multiline", [r"^train/windows_per_s$"]],
             "gradient norm (before clipping)": ["Multiline", [r"^train/grad_norm$"]]}
    base = {f"interpolation L2P@{n}": ["Multiline", [rf"^{re.escape(BASELINE)}/val/l2p@{n}$"]] for n in val_lengths}
    return {"1 val: model / interpolation (< 1: better)": ratio, "2 test: fill and network / interpolation": test,
            "3 val: model": model, "4 train": train, "5 interpolation baseline": base}


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
        """The run's HParams trial id, from its folder ``<label>/<start time>`` (:func:`~inbetweening.training.tb_runs.
        trial_id`: ``19:21:49 zero layer (2026-11-25)``)."""
        return trial_id(str(self.name or ""), str(self.version or ""))

    def log_metrics(self, metrics: Mapping[str, float], step: int | None = None) -> None:
        renamed = {self.RENAME.get(k, "train/lr" if k.startswith("lr-") else k): v for k, v in metrics.items()}
        if any(k.startswith("val/") for k in renamed) and step is not None:
            self.last_val_step = int(step)
        elif renamed and self.last_val_step is not None and all(
                k.startswith(("test/", "test_network/", f"{BASELINE}/test/")) for k in renamed):
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

    def start_session(self, hparams: Mapping, shown: Sequence[str], metrics: Sequence[str],
                      layout: dict | None = None) -> None:
        """Write this run's session start (its ``hparams`` values, trial id :attr:`trial_id`) and the Custom Scalars
        ``layout``, and add ``shown`` and ``metrics`` to the folder's HParams columns (:func:`update_columns`).  Once
        per logger."""
        if self._session_started or self.experiment is None:
            return
        from tensorboard.plugins.hparams import summary_v2 as hp_summary

        self._write(hp_summary.hparams_pb(dict(hparams), trial_id=self.trial_id or None))
        if layout:
            self.experiment.add_custom_scalars(layout)
        update_columns(self.save_dir, hparams, shown, metrics, self.trial_id)
        self._session_started = True

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
    marks it failed if fitting raises.  ``hparams``, ``shown``: :func:`~inbetweening.training.tb_runs.curated_hparams`
    (``shown``: the swept keys of a sweep's job, the keys a single run's command line set; the folder's columns,
    :func:`update_columns`)."""

    def __init__(self, hparams: Mapping, shown: Sequence[str], val_lengths: Sequence[int], test_lengths: Sequence[int],
                 end_at_fit_end: bool = False):
        self.hparams, self.shown, self.end_at_fit_end = dict(hparams), list(shown), end_at_fit_end
        self.val_lengths, self.test_lengths = list(val_lengths), list(test_lengths)

    def start(self, trainer: L.Trainer) -> None:
        if not trainer.is_global_zero:
            return
        for lg in trainer.loggers:
            if isinstance(lg, RunLogger):
                lg.start_session(self.hparams, self.shown, hparams_metrics(self.test_lengths, self.val_lengths),
                                 custom_scalars_layout(self.val_lengths, self.test_lengths))

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
