"""Case files kept here are run by the tests that name them (e.g.
tests/acceptance/test_pole_case.py), not collected as cases by the bench's pytest plugin."""

collect_ignore_glob = ["*.toml"]
