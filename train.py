"""Train an NR-IQA model on one fold: ``python train.py experiment=fcnn data.val_scene=NAME``.

Configs live in ``configs/`` (start at ``configs/train.yaml``); see ``--help`` for the groups.
Returns the metric named by ``optimized_metric`` so that Hydra sweepers can optimise it.
"""

import sys

import hydra
from omegaconf import DictConfig

from nriqa.training import set_project_root, train, user_error

set_project_root()


@hydra.main(config_path="configs", config_name="train", version_base="1.3")
def main(cfg: DictConfig) -> float | None:
    try:
        metrics, objects = train(cfg)
    except Exception as exc:
        message = user_error(exc)
        if message is None:
            raise
        sys.exit(f"error: {message}")
    print(f"best checkpoint: {objects['best_ckpt'] or '(none)'}; {objects['seconds']:.1f} s")
    return metrics.get(cfg.get("optimized_metric"))


if __name__ == "__main__":
    main()
