# Two commands on a fresh machine: `make run` and `make test`.
# Both install from requirements.lock (exact versions, hashes): the versions the suite passed with.
# pyproject.toml keeps version ranges for library users; `make lock` re-resolves the lock from them.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
LOCK   := requirements.lock
STAMP  := $(VENV)/.installed-stamp
# the resolver that writes the lock, itself pinned so a refresh is reproducible
UV     := uv==0.13.9

.PHONY: run test test-fast docs bench install lock clean

# the compiled engines' sources (impact/kernel_cache.py COMPILED_SOURCES): a change recompiles them
KERNELS := $(addprefix impact/,event_rules.py columns.py horn.py kernel_blocks.py kernel.py kernel_energy.py \
             kernel_contact.py kernel_modal.py rock.py drill_kernel.py compliant.py kernel_compliant.py kernel_drill_compliant.py \
             kernel_cache.py)

$(STAMP): pyproject.toml $(LOCK) $(KERNELS)
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --require-hashes -r $(LOCK)
	# the project itself on top of the locked set: no dependency may be resolved again here
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	$(PY) -m pip check
	# compile the impact kernel now (numba caches it beside the source): runs start at once
	$(PY) -c "from impact.kernel import warmup; warmup(); from impact.kernel_modal import warmup as w; w(); from impact.compliant_engine import warmup as c; c(); from impact.kernel_drill_compliant import warmup as d; d()"
	touch $(STAMP)

install: $(STAMP)

# every supported Python and platform in one file (markers select per machine); the build
# backend is locked too, since the editable install above builds without isolation
lock:
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet $(UV)
	printf 'setuptools>=68\nwheel\n' | $(VENV)/bin/uv pip compile pyproject.toml - --extra test --extra docs \
		--universal --python-version 3.11 --generate-hashes --quiet -o $(LOCK)

run: $(STAMP)
	$(PY) -m results

# two pytest workers (CI's two cores), whole files per worker so a module's fixture is computed
# once; the numeric libraries single-threaded in each so the workers do not contend for the cores
# (measured in the working tree: 8 min 32 s sequential -> 4 min 55 s)
test: $(STAMP)
	OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
		$(PY) -m pytest -q -n 2 --dist loadfile

# the daily tier: every test not marked slow, under a minute on 2 cores
test-fast: $(STAMP)
	OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
		$(PY) -m pytest -q -n 2 --dist loadfile -m "not slow"

# the documentation site: warnings are errors, the gallery's examples run during the build; the
# verification manual's numbers come from the tests marked vv, run first (stale records removed);
# then every internal link and the front page in a headless browser (docs/check_site.py)
docs: $(STAMP)
	rm -f docs/_generated/vv/*.json
	OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
		$(PY) -m pytest -q -m vv -p no:cacheprovider
	MPLBACKEND=Agg PYVISTA_OFF_SCREEN=true OMP_NUM_THREADS=1 \
		$(PY) -m sphinx -W --keep-going -q -b html docs docs/_build/html
	$(PY) docs/check_site.py

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache docs/_build docs/gallery
