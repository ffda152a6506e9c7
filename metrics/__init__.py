"""Evaluation metrics and the evaluation protocol."""
