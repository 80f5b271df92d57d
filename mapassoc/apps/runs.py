"""Running the estimator on files: what ``mapassoc run`` and ``mapassoc demo`` share."""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path
from typing import TextIO

from mapassoc import __version__

__all__ = ["json_dump", "run_files"]


class _Progress:
    """A one-line progress bar on stderr (only when stderr is a terminal)."""

    def __init__(self, stream: TextIO, enabled: bool) -> None:
        self.stream = stream
        self.enabled = enabled and stream.isatty()

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        width = 30
        filled = int(width * done / total) if total else width
        self.stream.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} scans")
        if done >= total:
            self.stream.write("\n")
        self.stream.flush()


def json_dump(data: object, path: Path) -> None:
    path.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n", encoding="utf-8")


def run_files(
    config_path: str | Path,
    detections_path: str | Path,
    out_dir: str | Path,
    *,
    timings: bool = True,
    progress: bool = True,
) -> dict[str, object]:
    """Read a configuration and a detections file, estimate tracks, write the outputs.

    Writes ``windows.jsonl`` line by line while the run goes on, then ``tracks.csv``
    and ``summary.json``.  Returns the summary.
    """
    from mapassoc.data.config import load_config
    from mapassoc.data.io import read_detections, write_tracks
    from mapassoc.estimator.pipeline import WindowEstimator

    config = load_config(config_path)
    scans = read_detections(detections_path, config.sensors)
    estimator = WindowEstimator(config=config)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with (
        (out / "windows.jsonl").open("w", encoding="utf-8") as stream,
        warnings.catch_warnings(record=True) as caught,
    ):
        warnings.simplefilter("always")

        def on_window(report: object) -> None:
            stream.write(json.dumps(report.to_json(timings=timings), allow_nan=False) + "\n")  # type: ignore[attr-defined]
            stream.flush()

        result = estimator.run(scans, progress=_Progress(sys.stderr, progress), on_window=on_window)
    write_tracks(out / "tracks.csv", result.tracks)
    summary: dict[str, object] = {
        "mapassoc_version": __version__,
        "config": str(config_path),
        "detections": str(detections_path),
        **result.summary(timings=timings),
        "warnings": [str(w.message) for w in caught],
    }
    json_dump(summary, out / "summary.json")
    for w in caught:
        print(f"mapassoc: warning: {w.message}", file=sys.stderr)
    return summary
