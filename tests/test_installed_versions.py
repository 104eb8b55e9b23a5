"""run.json's software versions are what importlib.metadata says; the platform text is
platform.platform()'s without the processor."""

from __future__ import annotations

import platform
from importlib import metadata

import pytest

from toggle_cosim.cosim import outcome


def test_versions_are_importlib_metadatas() -> None:
    versions = dict(outcome.installed_versions())
    for name in outcome.RECORDED_PACKAGES:
        try:
            expected = metadata.version(name)
        except metadata.PackageNotFoundError:
            expected = "not installed"
        assert versions[name] == expected, name


def test_a_package_that_is_not_there_is_not_installed(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(outcome, "RECORDED_PACKAGES", ("no-such-package-xyz",))
    outcome.installed_versions.cache_clear()
    try:
        assert dict(outcome.installed_versions())["no-such-package-xyz"] == "not installed"
    finally:
        outcome.installed_versions.cache_clear()


def test_the_platform_text_is_platform_platforms() -> None:
    uname = platform.uname()
    if uname.processor not in ("", uname.machine):
        pytest.skip(f"processor {uname.processor!r} differs from machine {uname.machine!r} here")
    assert outcome.platform_text() == platform.platform()
