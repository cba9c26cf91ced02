"""Evaluation: the LAFAN1 benchmark protocol, torchmetrics metrics, result collection."""
