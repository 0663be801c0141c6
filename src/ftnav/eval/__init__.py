"""Evaluation: error, consistency (NEES) and fault-detection metrics (spec §11)."""
