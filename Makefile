# fem_runout — two commands for a newcomer: `make demo` and `make test`.
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
MPIEXEC := $(VENV)/bin/mpiexec
NP ?= 2
export NUMBA_NUM_THREADS := 1
export OMP_NUM_THREADS := 1
export OPENBLAS_NUM_THREADS := 1
# the serial tests run in WORKERS pytest-xdist processes (one per core), a file per worker
WORKERS ?= 2
SERIAL_TIMEOUT ?= 1800
MPI_TIMEOUT ?= 1200
DEMO_CASE ?= cases/inclined_dam_break.yaml
# rank independence on 3 ranks too (mpich runs 3 on 2 cores): dam breaks on and off the cuts,
# the TG2/DAMPM rank comparisons and the hard cases
RANK3_TESTS ?= tests/mpi/test_partition_cut.py tests/mpi/test_cell_kernels_mpi.py tests/mpi/test_tg2_mpi.py \
	tests/mpi/test_exact_sums_mpi.py tests/mpi/test_partition_mpi.py tests/mpi/test_terrain_mpi.py \
	tests/mpi/test_mpm_mpi.py tests/mpi/test_hard_cases_mpi.py tests/mpi/test_ensemble_mpi.py \
	tests/mpi/test_restart_mpi.py tests/mpi/test_quadmesh_mpi.py tests/mpi/test_shared_nodes_mpi.py \
	tests/mpi/test_output_mpi.py

.PHONY: setup demo test test-serial test-mpi lint bench bench-peers clean

setup: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml requirements.lock scripts/find_python.sh
	@set -e; PYTHON=$$(bash scripts/find_python.sh); \
	if [ ! -x $(PY) ]; then echo "creating $(VENV) with $$PYTHON"; $$PYTHON -m venv $(VENV); fi; \
	$(PY) -m pip install -q --upgrade pip; \
	$(PY) -m pip install -q -c requirements.lock -e '.[dev]'; \
	touch $@

demo: setup
	$(MPIEXEC) -n $(NP) $(PY) -m fem_runout $(DEMO_CASE) --overwrite
	@echo "results: results/inclined_dam_break/ (fields.bp for ParaView, series.csv, *.png)"

test: setup
	@status=0; \
	$(VENV)/bin/ruff check fem_runout mpm tests peers || status=1; \
	timeout $(SERIAL_TIMEOUT) $(PY) -m pytest -q -x -n $(WORKERS) --dist loadfile tests \
		--ignore=tests/mpi --durations=15 || status=1; \
	timeout $(MPI_TIMEOUT) $(MPIEXEC) -n $(NP) $(PY) -m pytest -q -x tests/mpi || status=1; \
	timeout $(MPI_TIMEOUT) $(MPIEXEC) -n 3 $(PY) -m pytest -q -x $(RANK3_TESTS) || status=1; \
	exit $$status

lint: setup
	$(VENV)/bin/ruff check fem_runout mpm tests peers

# the suite runs every benchmark with every implemented method on 1 and 2 ranks (< 30 min);
# footprint: avaKot on its DEM and on a 4x larger padded one, both methods (about 6 min);
# meshes: TG2-PC on gmsh meshes against the grid, Thacker, hemisphere, avaKot (docs/meshes.md);
# corridor-spread: the avaKot corridor against the 5 m grid over 6 perturbed draws each (~27 min);
# the TG2-only fine-grid report is `$(PY) -m fem_runout.bench tg2-report` (about 12 min)
bench: setup
	$(PY) -m fem_runout.bench suite --ranks 1 2 3 --out docs/benchmarks.md --figures docs/figures
	$(PY) -m fem_runout.bench step-cost --cells 250 --steps 20 --ranks 1 2 --out docs/step_cost.md
	$(PY) -m fem_runout.bench step-cost --cells 250 --steps 20 --ranks 1 2 \
		--case cases/hemisphere_bingham.yaml --out docs/step_cost_rheology.md
	$(PY) -m fem_runout.bench step-cost --method mpm --cells 50 158 500 --steps 10 --ranks 1 2 \
		--set 'initial.depth=1 + sqrt(maximum(25 - (x-25)**2 - (y-25)**2, 0))' \
		--out docs/step_cost_dampm.md
	@if [ -f "$${FEM_RUNOUT_DATA:-../shared/data}/avaKot/avaKot.asc" ]; then \
		$(PY) -m fem_runout.bench footprint --out docs/performance.md; \
		$(PY) -m fem_runout.bench scaling --side-by-side --out docs/performance.md; \
		$(MPIEXEC) -n 2 $(PY) -m fem_runout.bench meshes --out docs/meshes.md; \
		$(MPIEXEC) -n 2 $(PY) -m fem_runout.bench corridor-spread --members 6 --out docs/meshes.md; \
	else echo "footprint: skipped, no avaKot data under FEM_RUNOUT_DATA (docs/real_terrain.md)"; \
		$(MPIEXEC) -n 2 $(PY) -m fem_runout.bench meshes --only thacker hemisphere \
			--out docs/meshes.md; fi

# peers side by side (optional, not in `make test`): GeoClaw (clawpack built from its sdist; needs
# gfortran from the system's package manager) and AvaFrame com1DFA in their own virtualenvs under
# ~/.cache/fem_runout/peers, then alternating runs with both methods -> docs/peers.md (~15 min)
PEER_ROUNDS ?= 3
bench-peers: setup
	bash peers/geoclaw/setup.sh
	bash peers/com1dfa/setup.sh
	$(PY) -m fem_runout.bench side-by-side --rounds $(PEER_ROUNDS) --out docs/peers.md \
		--figure docs/figures/peers_avakot.png

clean:
	rm -rf results .pytest_cache
