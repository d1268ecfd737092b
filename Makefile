# Every target sets up .venv on first use, so a fresh clone needs only Python 3.11 and make.
PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test bench bench-diagnosis lint format clean tools

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test]"
	@touch $(STAMP)

# make demo DEMO_ARGS=--dashboard: real time (x60: the load cycle takes about 16.5 min) with the
# live dashboard in a browser
demo: $(STAMP)
	$(BIN)/python -m hil_client.demo $(DEMO_ARGS)

# mbpoll and libmodbus (Debian) are Modbus clients the project did not write (socat joins
# mbpoll to the RTU server's pty); their interop tests are skipped where they cannot be
# installed (no root, no apt-get).
tools:
	@command -v mbpoll >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null \
	  && (apt-get update -qq && apt-get install -y -qq mbpoll) >/dev/null 2>&1; } \
	  || echo "note: mbpoll not installed; its interop test will be skipped"
	@test -f /usr/include/modbus/modbus.h || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null \
	  && (apt-get update -qq && apt-get install -y -qq libmodbus-dev gcc) >/dev/null 2>&1; } \
	  || echo "note: libmodbus-dev not installed; the libmodbus C client test will be skipped"
	@command -v socat >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null \
	  && (apt-get update -qq && apt-get install -y -qq socat) >/dev/null 2>&1; } \
	  || echo "note: socat not installed; mbpoll's RTU test over a pty pair will be skipped"
	@command -v chromium >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null \
	  && (apt-get update -qq && apt-get install -y -qq chromium) >/dev/null 2>&1; } \
	  || echo "note: chromium not installed; the dashboard's browser test will be skipped"

# a test file per worker (module fixtures are built once); three workers on two cores: many
# tests wait on real time (servers, pauses, timeouts), and a third worker uses the cores
# meanwhile (a cold-cache CI run: 740 s with three, 788 s with two)
test: $(STAMP) tools
	$(BIN)/python -m pytest -q -n 3 --dist loadfile

# speed and memory figures (a few minutes)
bench: $(STAMP)
	$(BIN)/python bench/run_bench.py
	$(BIN)/python bench/bench_modbus.py
	$(BIN)/python bench/bench_dashboard.py
	$(BIN)/python bench/bench_clock.py
	$(BIN)/python bench/bench_faults.py
	$(BIN)/python bench/fuzz_modbus.py
	$(BIN)/python bench/bench_transports.py
	$(BIN)/python bench/bench_logio.py

# the gap diagnosis against the independent plants (about 30 min on 2 cores)
bench-diagnosis: $(STAMP)
	$(BIN)/python bench/reality_gap.py 20
	$(BIN)/python bench/reality2_gap.py --cases 20
	for plant in reality3 reality4 reality5 reality6 reality7 reality8 reality9 reality10; do \
		$(BIN)/python bench/reality2_gap.py --cases 20 --plant $$plant || exit 1; \
	done

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

format: $(STAMP)
	$(BIN)/ruff format .
	$(BIN)/ruff check --fix .

clean:
	rm -rf $(VENV) out .pytest_cache
