"""``train(cfg)``: the job behind ``train.py`` (its parts are built by :mod:`inbetweening.training.builders`): fit,
calibrate the do-no-harm blend, run the test benchmark and write ``benchmark.json``; and what a fit checks before it
starts from a checkpoint (:func:`start_from`: ``init_from``; :func:`check_resume`: ``ckpt_path``)."""
from __future__ import annotations

from pathlib import Path

import lightning as L
import torch
import yaml
from lightning.pytorch.utilities.exceptions import SIGTERMException
from omegaconf import DictConfig

from inbetweening.atomic import write_text
from inbetweening.data.datasets import DatasetError
from inbetweening.evaluation import benchmark as B
from inbetweening.predictor.checkpoint import CheckpointError, kept_start, predictor_state, read_checkpoint
from inbetweening.training.builders import make_datamodule, make_module, make_trainer, output_dir
from inbetweening.training.calibrate import calibrate_module
from inbetweening.training.callbacks import trim_heap
from inbetweening.training.config import fill_settings, validate
from inbetweening.training.datamodule import InbetweenDataModule
from inbetweening.training.evaluate import score_keyframes, with_baselines
from inbetweening.training.job import use_threads, write_benchmark
from inbetweening.training.module import InbetweenModule, load_module
from inbetweening.training.sampling import rank_world
from inbetweening.training.tb_logging import HParamsSession, RunLogger

__all__ = ["check_resume", "start_from", "train"]


def train(cfg: DictConfig) -> dict[str, float]:
    """Fit (unless the model is a non-trainable baseline), then run the test benchmark with the best
    checkpoint and write ``benchmark.json``.  Returns the test metrics."""
    validate(cfg)
    use_threads(cfg)
    L.seed_everything(cfg.seed, workers=True)
    out = output_dir(cfg)
    dm = make_datamodule(cfg)
    dm.prepare_data()
    init = start_from(cfg.get("init_from"), dm)
    dm.setup("fit")
    report_derived(dm.data, out)
    module = make_module(cfg, dm, init)
    module.compile_network(bool(cfg.get("compile", False)))
    trainer = make_trainer(cfg)
    ckpt_path = cfg.get("ckpt_path")
    if ckpt_path:
        check_resume(ckpt_path, module)
    best = None
    if module.trainable and cfg.trainer.get("max_steps", -1) != 0:
        try:
            trainer.fit(module, datamodule=dm, ckpt_path=ckpt_path, weights_only=True)
        except SIGTERMException:  # (a SystemExit) the checkpoint and the resume hint were written
            raise SystemExit(143) from None
        except SystemExit:  # Lightning exits after a graceful Ctrl-C; the checkpoint and hint were written
            raise SystemExit(130) from None
        best = getattr(trainer.checkpoint_callback, "best_model_path", None) or None
    if best and Path(best).exists():
        module = load_module(best)
    else:
        best = None
    if best and float(cfg.get("init_keep") or 0) > 0:  # weight-space ensembling with the start, against forgetting
        mixed = kept_start(read_checkpoint(best), init, float(cfg.init_keep))
        best = str(Path(best).with_name("kept_start.ckpt"))
        if rank_world()[0] == 0:
            torch.save(mixed, best)
            print(f"the weights taken {float(cfg.init_keep):g} of the way back to init_from's: {best}")
        module.load_state_dict(mixed["state_dict"])
    fitted = module.trainable and cfg.trainer.get("max_steps", -1) != 0
    if fitted and cfg.get("calibrate", True) and (best or cfg.get("run_test", True)):
        # every rank fits the same blend; rank 0 writes it
        best = calibrate_module(module, dm, cfg, best, write=rank_world()[0] == 0,
                                max_gap=int(dm.hparams.transition_max)) or best
    metrics: dict[str, float] = {}
    if cfg.get("run_test", True):
        trim_heap()  # the test batches start from the heap the training steps left
        test_trainer = make_trainer(cfg, callbacks=False, loggers=False)
        test_trainer.test(module, datamodule=dm, verbose=False)
        metrics = dict(module.test_results)
        name = cfg.model.name
        network = network_alone(module, dm, cfg) if module.predictor.blend is not None else None
        if not test_trainer.is_global_zero:  # DDP: metrics are synced; rank 0 alone writes and prints
            return metrics
        kf = None
        if cfg.get("test_keyframes"):  # the keyframes-only protocol on the whole test clips, through the animator path
            kf = score_keyframes(module.predictor, dm.data, list(cfg.test_keyframes), int(cfg.seed),
                                 bool(cfg.get("foot_lock", True)), cfg.get("keyframe_clips"),
                                 bool(cfg.get("self_check", True)), fill_settings(cfg))
        rows = with_baselines(name, metrics, dm, cfg.data.test_lengths)
        write_benchmark(out / "benchmark.json", dm.data.name, name, len(dm.test_set), metrics, dm.hparams.split,
                        keyframes=kf, interpolation=rows.get("interpolation"),
                        network=network[0] if network else None)
        print(f"\nTest benchmark ({dm.data.name}, split {dm.hparams.split}, {len(dm.test_set)} windows, "
              f"checkpoint: {best or 'final weights'})")
        print(B.format_table(rows, cfg.data.test_lengths))
        if network:
            print("The network alone (without the do-no-harm blend):\n"
                  + B.format_table({name: network[0], "interpolation": rows["interpolation"]}, cfg.data.test_lengths))
        if "recovery_rmse" in metrics:
            print(f"mocap recovery: RMSE of recovered joint positions = {metrics['recovery_rmse']:.3f}")
        if kf is not None:
            from inbetweening.evaluation.keyframes import format_table

            print(f"\nKeyframes-only protocol ({len(dm.data.test)} whole test clips)\n" + format_table(kf))
        log_test(trainer, module, network[1] if network else None)
    return metrics


def network_alone(module: InbetweenModule, dm, cfg: DictConfig) -> tuple[dict, dict]:
    """The test benchmark of the network without its do-no-harm blend (the blended fill's figures are the ``test/``
    ones): ``(metrics, TensorBoard scalars under test_network/)``; the module's blend and test results are left as
    they were."""
    blend, results, logs = module.predictor.blend, dict(module.test_results), dict(module.stage_logs.get("test", {}))
    module.predictor.blend = None
    try:
        make_trainer(cfg, callbacks=False, loggers=False).test(module, datamodule=dm, verbose=False)
        net = dict(module.test_results)
        scalars = {"test_network/" + k[len("test/"):]: v for k, v in module.stage_logs.get("test", {}).items()
                   if k.startswith("test/")}
    finally:
        module.predictor.blend, module.test_results, module.stage_logs["test"] = blend, results, logs
    return net, scalars


def report_derived(data, out: Path) -> None:
    """``data=bvh``: print what was derived from the files, once, and save it as ``dataset.yaml`` next to the run."""
    if data.derived is None or rank_world()[0] != 0:
        return
    text = yaml.safe_dump(data.derived, sort_keys=False, width=118, default_flow_style=None)
    write_text(out / "dataset.yaml", text)
    print(f"\nDataset derived from the files of data.path (saved as {out / 'dataset.yaml'}; data.<key>=... overrides "
          f"any value):\n{text}")


def log_test(trainer: L.Trainer, module: InbetweenModule, network: dict | None = None) -> None:
    """The test scalars (``test/l2p@15``, ``~interpolation/test/l2p@15``, ``test/l2p_ratio@15``, ...: the fill as the
    tools deliver it, blend included; ``network``: the network alone's, ``test_network/...``) into the fit's
    TensorBoard run at its last step, and its HParams session marked ended."""
    for cb in trainer.callbacks:
        if isinstance(cb, HParamsSession):
            cb.start(trainer)  # a baseline was not fitted: its session starts here
    for lg in trainer.loggers:
        if isinstance(lg, RunLogger):
            lg.log_metrics({**module.stage_logs.get("test", {}), **(network or {})}, step=trainer.global_step)
            lg.end_session("success")
        lg.finalize("success")


def start_from(path: str | None, dm: InbetweenDataModule) -> dict | None:
    """``init_from``: the checkpoint a new run starts from (read safely), after putting the data's joints in the
    checkpoint's order (matched by name: the same joints and hierarchy in another order are fine).  A checkpoint of
    another skeleton is one :class:`CheckpointError` naming both skeletons."""
    if not path:
        return None
    ckpt = read_checkpoint(path)
    theirs = ckpt["hyper_parameters"]["skeleton"]
    names, parents = list(theirs["names"]), list(theirs["parents"])
    data = dm.load_data()
    mine = data.skeleton
    try:
        ordered = data.in_joint_order(names)
    except DatasetError as e:
        ordered = None
        why = str(e)
    if ordered is not None and list(ordered.skeleton.parents) != parents:
        ordered, why = None, "the same joints under other parents"
    if ordered is None:
        raise CheckpointError(f"init_from: {path} was trained on a {len(names)}-joint skeleton ({', '.join(names[:4])}, "
                              f"...); data {data.name!r} has {mine.num_joints} joints ({', '.join(mine.names[:4])}, "
                              f"...): {why}")
    dm.use_data(ordered)
    return ckpt


def _architecture(model: dict) -> str:
    return ", ".join(f"{k}={v}" for k, v in sorted(model.items()) if k != "name") or "defaults"


def check_resume(path: str, module: InbetweenModule) -> dict:
    """The checkpoint a fit resumes from, read safely and checked to fit this run's network: same skeleton, same
    parameter shapes; :class:`CheckpointError` naming both architectures otherwise (never a size-mismatch traceback)."""
    ckpt = read_checkpoint(path)
    hp = ckpt["hyper_parameters"]
    theirs, ours = predictor_state(ckpt["state_dict"]), module.predictor.state_dict()
    mine = dict(module.hparams["model"])
    old = dict(hp.get("model", {}))
    j_old, j_new = len(hp.get("skeleton", {}).get("names", [])), module.skeleton.num_joints
    if j_old != j_new:
        raise CheckpointError(f"ckpt_path: {path} was trained on a {j_old}-joint skeleton; this run's data "
                              f"{module.hparams.get('dataset', '')!r} has {j_new} joints: resume on the same data")
    bad = sorted(k for k in ours.keys() & theirs.keys() if tuple(ours[k].shape) != tuple(theirs[k].shape))
    missing = sorted(ours.keys() ^ theirs.keys())
    if bad or missing or old.get("name") != mine.get("name"):
        raise CheckpointError(
            f"ckpt_path: {path} holds another architecture: {old.get('name')} ({_architecture(old)}); this run builds "
            f"{mine.get('name')} ({_architecture(mine)}): resume with the checkpoint's model settings, or start a new "
            "run without ckpt_path")
    return ckpt
