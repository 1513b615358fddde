"""Benchmarks: each measures one concern and writes its page under docs/measurements/ (see benchlib)."""
