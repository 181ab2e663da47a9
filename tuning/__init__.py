"""Gain tuning for smibjax: `python -m tuning.optimize`."""
