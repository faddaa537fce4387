"""The lock file that ``make run`` / ``make test`` install from agrees with pyproject's ranges.

A dependency added to or narrowed in ``pyproject.toml`` without ``make lock`` would leave the lock
installing something the project does not allow (or missing a package): these checks catch that
without a network, from the two files alone.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest
from packaging.markers import Marker
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]
LOCK = ROOT / "requirements.lock"

# Environments the lock must serve: every Python the project supports, on the platforms it is used on.
ENVIRONMENTS = [
    {"python_version": v, "python_full_version": f"{v}.0", "platform_machine": m, "sys_platform": s,
     "platform_system": ps, "os_name": os_name, "implementation_name": "cpython",
     "platform_python_implementation": "CPython", "extra": ""}
    for v in ("3.11", "3.12", "3.13")
    for m, s, ps, os_name in (("x86_64", "linux", "Linux", "posix"), ("aarch64", "linux", "Linux", "posix"),
                              ("AMD64", "win32", "Windows", "nt"), ("arm64", "darwin", "Darwin", "posix"))
]


def _pins() -> list[tuple[str, Version, Marker | None, int]]:
    """(name, version, marker, number of hashes) of every entry of the lock."""
    text = LOCK.read_text()
    pins = []
    for block in re.split(r"\n(?=[A-Za-z0-9])", text):
        head = block.splitlines()[0]
        if head.startswith("#") or not head.strip():
            continue
        spec = head.rstrip(" \\")
        name_ver, _, marker = spec.partition(";")
        name, _, ver = name_ver.strip().partition("==")
        pins.append((canonicalize_name(name), Version(ver), Marker(marker.strip()) if marker.strip() else None,
                     block.count("--hash=sha256:")))
    return pins


def _requirements() -> list[Requirement]:
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    reqs = [Requirement(r) for r in meta["project"]["dependencies"]]
    for extra in ("test", "docs"):
        reqs += [Requirement(r) for r in meta["project"]["optional-dependencies"][extra]]
    reqs += [Requirement(r) for r in meta["build-system"]["requires"]]
    return reqs


def test_every_pin_is_exact_and_hashed():
    pins = _pins()
    assert len(pins) > 30
    for name, _ver, _marker, n_hash in pins:
        assert n_hash >= 1, f"{name} has no hash in {LOCK.name}"


@pytest.mark.parametrize("env", ENVIRONMENTS, ids=lambda e: f"py{e['python_version']}-{e['platform_machine']}")
def test_the_lock_satisfies_pyproject_on_every_supported_environment(env):
    """Each direct requirement that applies in ``env`` has exactly one pin there, inside its range."""
    pins = _pins()
    for req in _requirements():
        if req.marker is not None and not req.marker.evaluate(env):
            continue
        name = canonicalize_name(req.name)
        chosen = [v for n, v, m, _ in pins if n == name and (m is None or m.evaluate(env))]
        assert len(chosen) == 1, f"{req}: {len(chosen)} pins apply on {env['python_version']}/{env['platform_machine']}"
        assert req.specifier.contains(chosen[0], prereleases=True), f"{name}=={chosen[0]} is outside {req.specifier}"
