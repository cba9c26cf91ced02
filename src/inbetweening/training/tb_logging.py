"""What a run writes to TensorBoard besides Lightning's scalars, so that a researcher reads it at a glance:

- the scalar names (:func:`tb_scalars`): ``val/l2p@15`` and the ratio ``val/l2p_ratio@15`` (below 1: better than
  interpolation) in the model's groups, interpolation's value on the same windows in a group of its own that
  TensorBoard lists last (``~interpolation/val/l2p@15``, :data:`BASELINE`);
- where a run's events go and what it is called: :mod:`inbetweening.training.tb_runs`;
- :class:`RunLogger`: Lightning's TensorBoard logger with ``train/epoch`` and ``train/lr`` in the ``train`` group,
  the test scalars at the last validation's step, and an HParams session (:meth:`RunLogger.start_session`) written
  when fitting starts (running or interrupted runs appear) whose trial id is the run's path, unique per run;
- which run says the HParams dashboard's columns: only the jobs of a sweep write an HParams *experiment* (see
  :class:`HParamsSession`);
- :func:`custom_scalars_layout`: per metric and length one chart of the ratio to interpolation (the runs of a sweep
  as its lines), one of the model's values, the training curves each in a chart of its own;
- :class:`TrainStats`: windows/s, epoch time and gradient norm under ``train/``.
"""
from __future__ import annotations

import re
import time
from collections.abc import Mapping, Sequence

import lightning as L
import torch
from lightning.pytorch.loggers import TensorBoardLogger

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
    return logs


def hparams_metrics(test_lengths: Sequence[int], val_lengths: Sequence[int]) -> list[str]:
    """Metric columns of the HParams dashboard, in order (it shows the first 5 by default): best validation
    L2P, the test L2P ratios to interpolation, then the test L2P values, the validation ratios and L2Q/NPSS."""
    return ["val/l2p_mean_best", *[f"test/l2p_ratio@{n}" for n in test_lengths], *[f"test/l2p@{n}" for n in test_lengths],
            *[f"val/l2p_ratio@{n}" for n in val_lengths], "test/l2p_mean", *[f"test/l2q@{n}" for n in test_lengths],
            *[f"test/npss@{n}" for n in test_lengths]]


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
    marks it failed if fitting raises.  ``hparams``, ``shown``: :func:`~inbetweening.training.tb_runs.curated_hparams`.

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
