"""Exact and reference solutions used by the tests and the benchmarks (one module each)."""
