"""The suite's two tiers. A test marked ``full`` adds seeds, length or conditions to a property
the suite already tests with fewer (each such test names what guards its property in the
suite); it runs only with ``--run-full`` (``scripts/test --full``), and is otherwise deselected,
not skipped."""

import pytest


def pytest_addoption(parser):
    parser.addoption("--run-full", action="store_true", help="also run the long tier (tests marked `full`)")


def pytest_configure(config):
    config.addinivalue_line("markers", "full: the long tier, run by `scripts/test --full` (--run-full)")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--run-full"):
        return
    long_tier = [item for item in items if item.get_closest_marker("full")]
    if long_tier:
        config.hook.pytest_deselected(items=long_tier)
        items[:] = [item for item in items if not item.get_closest_marker("full")]
