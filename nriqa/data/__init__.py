"""Data: manifest dataset, folds, patch sampling, jitter, LightningDataModule."""
