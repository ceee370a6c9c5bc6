"""Where the shared datasets are, and the rule for tests that need them."""

import os
import pathlib

import pytest

SHARED = pathlib.Path(__file__).resolve().parents[2].parent / "shared"


def shared_file(relative):
    """The path of a file under ../shared, or a skip (a failure where
    CAIRN_REQUIRE_SHARED is set, as in CI)."""
    path = SHARED / relative
    if not path.is_file():
        if os.environ.get("CAIRN_REQUIRE_SHARED"):
            pytest.fail(f"CAIRN_REQUIRE_SHARED is set but {path} is missing")
        pytest.skip(f"{path} not found")
    return path
