"""The documented entry point ``inbetweening.datasets.load_dataset``; the data layer lives in :mod:`inbetweening.data`."""
from inbetweening.data.datasets import DatasetError, MotionData, load_dataset

__all__ = ["DatasetError", "MotionData", "load_dataset"]
