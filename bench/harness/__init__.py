"""The run harness."""
