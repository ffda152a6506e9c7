"""Mesh I/O and validation."""
