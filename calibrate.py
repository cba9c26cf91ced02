"""Fit the do-no-harm blend of a trained checkpoint on its data's validation windows (train.py does it after fitting):
    python calibrate.py ckpt_path=<run>/checkpoints/best.ckpt data=<name> [data.split=...] [out=<file>]
Writes <ckpt stem>.calibrated.ckpt beside it (or out=): the same network, plus one weight per gap length on its
correction to the interpolation (src/inbetweening/predictor/calibration.py)."""
import hydra
from omegaconf import DictConfig

from inbetweening.training.calibrate import calibrate
from inbetweening.training.job import run_cli


@hydra.main(version_base="1.3", config_path="conf", config_name="calibrate")
def main(cfg: DictConfig) -> None:
    run_cli(calibrate, cfg)


if __name__ == "__main__":
    main()
