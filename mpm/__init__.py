"""DAMPM: the depth-averaged material point method of the seed (§3.2) — issue 4.

It will reuse fem_runout's mesh, Q1 space, physics objects and runner; ``method: mpm`` is
refused with a clear message until then.
"""
