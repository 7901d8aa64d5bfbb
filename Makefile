# The README's two commands are `make demo` and `make test`; each sets up what is missing first.
VENV ?= .venv
PY := $(VENV)/bin/python
export PYOMO_CONFIG_DIR := $(CURDIR)/$(VENV)/share/pyomo
export MPLBACKEND := Agg

.PHONY: setup demo test bench bench-peers bench-mesh reproduce fuzz clean

setup:
	@./scripts/setup.sh

demo: setup
	$(VENV)/bin/ocdsl run configs/double_integrator.yaml --out runs/demo

test:
	@APT_EXTRA="chromium poppler-utils" ./scripts/setup.sh
	$(PY) -m pytest -q -m "not slow" -n 2 --timeout 600

bench: setup
	$(PY) -m ocdsl.bench

# published benchmarks beyond the examples, at their own (uniform) meshes: those present
PEERS_LIT := $(wildcard configs/lit_brachistochrone_wall.yaml configs/lit_catenary.yaml \
  configs/lit_free_flying_robot.yaml configs/lit_hypersensitive_linear.yaml configs/lit_linear_tangent.yaml \
  configs/lit_orbit_raising.yaml configs/lit_goddard_three_phase.yaml configs/lit_bryson_denham_touch.yaml)

bench-peers: setup
	$(PY) -c "from ocdsl.bench.cli import bench; bench()" configs/double_integrator.yaml \
	  configs/minimal_double_integrator.yaml configs/brachistochrone.yaml configs/bryson_denham.yaml \
	  configs/moon_landing.yaml configs/goddard.yaml configs/two_phase_double_integrator.yaml \
	  configs/seed0_rendezvous.yaml $(PEERS_LIT) \
	  --scaling configs/brachistochrone.yaml --series-solve 100
	$(PY) -m ocdsl.bench.derivatives configs > reports/bench/derivatives.md

# the adaptive-mesh table of docs/mesh.md (whole processes, one file at a time)
bench-mesh: setup
	nice -n 10 $(PY) -m ocdsl.bench.mesh configs/mesh_*.yaml

# 10,000 mutated configs/ files through the compile entry (tests/fuzzing.py): exit 1 on any
# exception other than a SpecError with a line, or a case over 5 s of CPU
fuzz: setup
	$(PY) tests/fuzzing.py --files 10000 --log runs/fuzz

reproduce: setup
	$(PY) -m ocdsl.report.reproduce
	$(PY) -m pytest -q -m slow --timeout 3600

clean:
	rm -rf runs .pytest_cache
