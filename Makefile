# Two commands on a fresh machine: `make run` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp

.PHONY: run test bench install clean

$(STAMP): pyproject.toml impact/kernel.py impact/kernel_modal.py
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	# compile the impact kernel now (numba caches it beside the source): runs start at once
	$(PY) -c "from impact.kernel import warmup; warmup(); from impact.kernel_modal import warmup as w; w()"
	touch $(STAMP)

install: $(STAMP)

run: $(STAMP)
	$(PY) -m results

# two pytest workers (CI's two cores), whole files per worker so a module's fixture is computed
# once; the numeric libraries single-threaded in each so the workers do not contend for the cores
# (measured in the working tree: 8 min 32 s sequential -> 4 min 55 s)
test: $(STAMP)
	OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
		$(PY) -m pytest -q -n 2 --dist loadfile

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
