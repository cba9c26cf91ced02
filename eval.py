"""Benchmark a checkpoint or a baseline:
    python eval.py data=<lafan1|bandai_namco|synthetic> data.path=<zip|folder> model=<zero_velocity|interpolation>
    python eval.py ckpt_path=<run>/checkpoints/last.ckpt data=...
Writes benchmark.json into the run directory (hydra.run.dir=... to choose it)."""
import hydra
from omegaconf import DictConfig

from inbetweening.retarget.task import eval_retarget, is_retarget
from inbetweening.training.evaluate import evaluate
from inbetweening.training.job import run_cli


@hydra.main(version_base="1.3", config_path="conf", config_name="eval")
def main(cfg: DictConfig) -> None:
    run_cli(eval_retarget if is_retarget(cfg) else evaluate, cfg)


if __name__ == "__main__":
    main()
