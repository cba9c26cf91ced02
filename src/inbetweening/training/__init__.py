"""Training: Lightning module and data module, losses, callbacks, config checks, train/eval jobs."""
