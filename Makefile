# Two commands on a fresh Debian 12 machine with Python 3.11 (see README):
#   make game   run the simulated two-robot game (headless)
#   make test   run the whole test suite
# Both create or reuse .venv/ (scripts/setup_venv.sh is idempotent: seconds when nothing changed).
VENV ?= .venv
PYTEST_ARGS ?=
GAME_ARGS ?=

.PHONY: setup game test bench clean
setup:
	@bash scripts/setup_venv.sh

game: setup
	$(VENV)/bin/air-hockey game $(GAME_ARGS)

# The whole suite: the tests without ROS nodes on two processes, then those with (marked `ros` by
# test/conftest.py) alone, one after another (README "Tests"). PYTEST_ARGS=... runs `pytest PYTEST_ARGS` once instead.
test: setup
ifeq ($(strip $(PYTEST_ARGS)),)
	$(VENV)/bin/python -m pytest -n 2 --dist loadfile -m "not ros"
	$(VENV)/bin/python -m pytest -m ros
else
	$(VENV)/bin/python -m pytest $(PYTEST_ARGS)
endif

clean:
	rm -rf build .pytest_cache
