"""Shared fixtures: the incise command line and the source tree, as CTest passes them."""

import os
import pathlib

import pytest


@pytest.fixture(scope="session")
def incise_executable():
    path = os.environ.get("INCISE_EXECUTABLE")
    if not path:
        pytest.skip("INCISE_EXECUTABLE is not set (CTest sets it)")
    return path


@pytest.fixture(scope="session")
def source_dir():
    return pathlib.Path(os.environ.get("INCISE_SOURCE_DIR",
                                       pathlib.Path(__file__).resolve().parents[2]))
