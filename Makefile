# make run  : render the default dataset (if missing), its convergence report, then train the default model
# make test : the test suite (fast; `make test-slow` adds the long runs)
PY := .venv/bin/python

.PHONY: run test test-slow setup
setup: .venv/.installed

.venv/.installed: pyproject.toml scripts/setup.sh
	bash scripts/setup.sh

run: .venv/.installed
	$(PY) -m data_gen preset=default out=data/default
	$(PY) -m data_gen.report data/default --out reports/data_default
	$(PY) train.py experiment=fcnn_fast

test: .venv/.installed
	$(PY) -m pytest -q

test-slow: .venv/.installed
	$(PY) -m pytest -q -m slow
