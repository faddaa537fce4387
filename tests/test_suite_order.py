"""The suite's own scheduling (tests/conftest.py): the files run heaviest first, xdist keeps that order."""

from pathlib import Path

import pytest

from conftest import HEAVY_FIRST, pytest_collection_modifyitems, pytest_configure

ROOT = Path(__file__).resolve().parents[1]


class _Item:
    def __init__(self, nodeid):
        self.nodeid, self.fixturenames, self.markers = nodeid, (), []

    def add_marker(self, marker):
        self.markers.append(marker)


def test_heavy_files_exist_once_and_go_first_in_their_order():
    assert len(set(HEAVY_FIRST)) == len(HEAVY_FIRST)
    for path in HEAVY_FIRST:
        assert (ROOT / path).is_file(), path
    light = ["tests/test_a.py::test_1", "tests/test_a.py::test_2"]
    heavy = [f"{HEAVY_FIRST[1]}::test_x", f"{HEAVY_FIRST[0]}::test_y", f"{HEAVY_FIRST[0]}::test_z[1]"]
    items = [_Item(n) for n in (light[0], heavy[0], light[1], heavy[1], heavy[2])]
    pytest_collection_modifyitems(None, items)
    assert [i.nodeid for i in items] == [heavy[1], heavy[2], heavy[0], *light]


def test_xdist_keeps_the_collection_order(pytestconfig):
    pytest.importorskip("xdist")

    class Config:
        class option:
            loadscopereorder = True

    pytest_configure(Config)
    assert Config.option.loadscopereorder is False
    assert pytestconfig.option.loadscopereorder is False        # this session's
