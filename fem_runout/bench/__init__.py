"""Benchmarks, run as ``python -m fem_runout.bench COMMAND``.

Commands:
    step-cost: TG2-PC wall time per step on an N x N mesh, serially and on 2 MPI ranks
        (:mod:`fem_runout.bench.step_cost`); writes a markdown table (``docs/step_cost.md``).
"""
