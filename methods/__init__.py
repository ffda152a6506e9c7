"""Simplification methods: external baselines and the suite's own implementations."""
