"""The path from windows to predictions: feature representation, masks, the predictor."""
