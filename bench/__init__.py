"""Benchmarks (not tests): env throughput against the bare physics and MPE2."""
