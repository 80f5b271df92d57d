"""``mapassoc demo`` follows the run-folder rules: it never replaces what it did not write."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from mapassoc.apps.cli import main
from mapassoc.apps.run_folders import DEMO_FORMAT, read_manifest


@pytest.fixture(scope="module")
def demo(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("demo") / "a" / "demo-out"  # parents created
    assert main(["demo", "--out", str(out)]) == 0
    return out


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def test_a_demo_folder_is_whole(demo: Path) -> None:
    names = sorted(p.name for p in demo.iterdir())
    assert names == ["manifest.json", "oracle_tracks.csv", "run", "scenario", "tracks.png"]
    manifest = read_manifest(demo, kind=DEMO_FORMAT)
    assert manifest is not None and manifest["status"] == "complete"
    assert (demo / "run" / "manifest.json").is_file()
    assert not demo.with_name("demo-out.partial").exists()


@pytest.mark.slow
def test_a_demo_is_replaced_only_with_overwrite_and_whole(
    demo: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "demo-out"
    out.mkdir()
    for path, data in _files(demo).items():
        (out / path).parent.mkdir(parents=True, exist_ok=True)
        (out / path).write_bytes(data)
    before = _files(out)
    assert main(["demo", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds a complete demo" in err and "--overwrite" in err
    assert _files(out) == before
    # --overwrite --no-plot: a whole new demo, without the previous run's PNG.
    assert main(["demo", "--out", str(out), "--overwrite", "--no-plot"]) == 0
    assert not (out / "tracks.png").exists()
    after = _files(out)
    assert after["run/tracks.csv"] == before["run/tracks.csv"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demo-out"]


@pytest.mark.parametrize("options", [[], ["--overwrite"]])
def test_a_folder_that_is_no_demo_is_never_replaced(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], options: list[str]
) -> None:
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("keep me")
    assert main(["demo", "--out", str(out), *options]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(out) in err and "demo" in err
    assert (out / "thesis.tex").read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine"]


def test_a_run_folder_is_no_demo_folder(
    demo: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--overwrite of a demo never replaces a run folder (a different kind of output)."""
    out = tmp_path / "run"
    out.mkdir()
    for path, data in _files(demo / "run").items():
        (out / path).write_bytes(data)
    before = _files(out)
    assert main(["demo", "--out", str(out), "--overwrite"]) == 2
    assert "not a mapassoc demo folder" in capsys.readouterr().err
    assert _files(out) == before


def test_without_matplotlib_the_demo_says_so_before_computing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    real = importlib.util.find_spec

    def no_matplotlib(name: str, *args: object, **kwargs: object) -> object:
        return None if name == "matplotlib" else real(name, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(importlib.util, "find_spec", no_matplotlib)
    out = tmp_path / "demo-out"
    assert main(["demo", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "matplotlib" in err and "--no-plot" in err and err.count("\n") == 1
    assert not out.exists() and not any(tmp_path.iterdir())
