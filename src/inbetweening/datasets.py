"""The documented entry point ``inbetweening.datasets.load_dataset``; the data layer lives in :mod:`inbetweening.data`.

A new dataset is one :class:`DatasetSpec` passed to :func:`register` (see :mod:`inbetweening.data.specs`).
"""
from inbetweening.data.datasets import DatasetError, MotionData, load_dataset
from inbetweening.data.specs import DATASETS, DatasetSpec, register

__all__ = ["DATASETS", "DatasetError", "DatasetSpec", "MotionData", "load_dataset", "register"]
