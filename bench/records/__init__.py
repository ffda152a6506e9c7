"""What a run leaves: the record schema and its table, the gate (``bench check``),
history, the papers' claims, the suites, and the statistics behind comparisons."""
