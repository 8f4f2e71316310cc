# Two commands on a fresh Debian 12 machine with Python 3.11 (see README):
#   make game   run the simulated two-robot game (headless)
#   make test   run the whole test suite
# Both create or reuse .venv/ (scripts/setup_venv.sh is idempotent: seconds when nothing changed).
VENV ?= .venv
PYTEST_ARGS ?= -n 2 --dist loadgroup  # two processes; the tests that start ROS nodes stay on one (test/conftest.py)
GAME_ARGS ?=

.PHONY: setup game test bench clean
setup:
	@bash scripts/setup_venv.sh

game: setup
	$(VENV)/bin/air-hockey game $(GAME_ARGS)

test: setup
	$(VENV)/bin/python -m pytest $(PYTEST_ARGS)

clean:
	rm -rf build .pytest_cache
