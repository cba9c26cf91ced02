"""Train an in-betweening model:  python train.py [overrides]   (see conf/train.yaml and README.md)."""
import hydra
from omegaconf import DictConfig

from inbetweening.retarget.task import is_retarget, train_retarget
from inbetweening.training.job import run_cli
from inbetweening.training.train import train


@hydra.main(version_base="1.3", config_path="conf", config_name="train")
def main(cfg: DictConfig) -> float | None:
    return run_cli(train_retarget if is_retarget(cfg) else train, cfg)


if __name__ == "__main__":
    main()
