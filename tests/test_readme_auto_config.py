"""The README's first configuration leaves every number the recording can give to it:
it loads without warnings, and every value the estimator can estimate is "auto"."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

from mapassoc.data.config import AUTO_BIRTH_KEYS, load_config

README = Path(__file__).resolve().parent.parent / "README.md"


def test_the_readme_configuration_is_all_auto(tmp_path: Path) -> None:
    (block,) = re.findall(r"```toml\n(.*?)```", README.read_text(encoding="utf-8"), re.DOTALL)
    path = tmp_path / "config.toml"
    path.write_text(block, encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        config = load_config(path)
    (name,) = config.sensors
    assert config.auto.names() == [
        "motion.noise_intensity",
        f"sensor '{name}' false_alarms_per_scan",
        f"sensor '{name}' detection_probability",
        f"sensor '{name}' noise_std",
        *(f"birth.{key}" for key in AUTO_BIRTH_KEYS),
    ]
