"""Data layer: BVH I/O, dataset specs and loading, the cache, synthetic data."""
