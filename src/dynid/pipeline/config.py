"""The identification config (TOML): model, tests and their roles, channels, conditioning, method.

    [model]
    example = "tx40"                 # or file = "robot.toml" (relative to this config)

    [[tests]]
    name = "exciting trajectory"
    role = "identify"                # or "validate" (cross-validation only)
    fs = 5000.0                      # sample rate when the files have no time column
    files = { q = "pos.csv", tau = "torques.csv" }

    [channels]                       # quantity -> channels, one per joint, with the file's unit
    q = { channels = ["Joint_1", "Joint_2"], unit = "rad" }
    tau = { channels = ["Joint_1", "Joint_2"], unit = "N.m" }

    [transmission]                   # optional: joint = matrix @ channels (+ offset)
    q = [["1/32", 0], [0, "1/32"]]
    q_offset = [0, "-pi/2"]
    tau = [[32, 0], [0, 32]]

    [conditioning]
    cutoff = 25.0                    # Hz, zero-phase Butterworth on positions
    order = 4
    border = 0.1                     # s trimmed at each end (default: the filter transient)
    decimate = [10, 10]
    min_speed = { 1 = 0.05 }         # rows of joint 1 dropped where |qd1| < 0.05

    [identification]
    method = "wls"                   # or "ols"
    known = { IA1 = 0.36 }           # fixed parameters: their contribution moves to Y
    poor_factor = 20.0

    [reference]                      # optional: a published base-parameter table to compare with
    file = "published.csv"
    names = { Izz = "ZZ" }
    combinations = { fvm6 = "1024*fvm6" }

Every error names the config file and the key, and says what is expected.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..model import ModelError
from ..model.files import parse_number
from .robot import Conditioning


class ConfigError(ModelError):
    """A config that cannot be used, naming the file and key."""


@dataclass(frozen=True)
class TestSpec:
    name: str
    role: str
    files: dict[str, Path]
    fs: float | None


@dataclass(frozen=True)
class ChannelSpec:
    channels: tuple[str, ...]
    unit: str | None


@dataclass(frozen=True)
class IdentifyConfig:
    path: Path
    model: str | Path
    tests: tuple[TestSpec, ...]
    channels: dict[str, ChannelSpec]
    transmission: dict[str, np.ndarray] = field(default_factory=dict)
    conditioning: Conditioning = field(default_factory=Conditioning)
    method: str = "wls"
    known: dict[str, float] = field(default_factory=dict)
    poor_factor: float = 20.0
    reference: dict[str, Any] | None = None


_TOP = {"model", "tests", "channels", "transmission", "conditioning", "identification", "reference"}


def load_config(path: str | Path) -> IdentifyConfig:
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the config ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    here = path.resolve().parent

    def err(key: str, msg: str) -> ConfigError:
        return ConfigError(f"{path}: [{key}] {msg}")

    unknown = set(data) - _TOP
    if unknown:
        raise ConfigError(f"{path}: unknown section(s) {sorted(unknown)}; sections: {sorted(_TOP)}")
    m = data.get("model", {})
    if "example" in m:
        model: str | Path = str(m["example"])
    elif "file" in m:
        model = here / m["file"]
    else:
        raise err("model", "give example = \"tx40\" (a shipped model) or file = \"model.toml\"")

    tests = []
    for i, t in enumerate(data.get("tests", []), start=1):
        key = f"tests {i}"
        if not isinstance(t.get("files"), dict) or not t["files"]:
            raise err(key, "needs files = { quantity = \"file\", ... }")
        role = t.get("role", "identify")
        if role not in ("identify", "validate"):
            raise err(key, f"role = {role!r}; use \"identify\" or \"validate\"")
        files = {q: here / f for q, f in t["files"].items()}
        for q, f in files.items():
            if not f.exists():
                raise err(key, f"file for {q!r} not found: {f}")
        fs = t.get("fs")
        tests.append(TestSpec(str(t.get("name", f"test {i}")), role, files, None if fs is None else float(fs)))
    if not any(t.role == "identify" for t in tests):
        raise err("tests", "at least one test must have role = \"identify\"")

    channels = {}
    for q, spec in data.get("channels", {}).items():
        if not isinstance(spec, dict) or "channels" not in spec:
            raise err(f"channels.{q}", "expected { channels = [...], unit = \"...\" }")
        channels[q] = ChannelSpec(tuple(spec["channels"]), spec.get("unit"))

    transmission = {}
    for k, v in data.get("transmission", {}).items():
        try:
            transmission[k] = np.array(
                [[parse_number(x, k) for x in row] if isinstance(row, list) else parse_number(row, k) for row in v])
        except ModelError as exc:
            raise err("transmission", str(exc)) from None

    c = data.get("conditioning", {})
    extra = set(c) - {"cutoff", "order", "border", "decimate", "min_speed"}
    if extra:
        raise err("conditioning", f"unknown key(s) {sorted(extra)}")
    decimate = c.get("decimate", [10, 10])
    cond = Conditioning(
        cutoff=float(c.get("cutoff", 25.0)),
        order=int(c.get("order", 4)),
        border=None if c.get("border") is None else float(c["border"]),
        decimate=tuple(int(x) for x in (decimate if isinstance(decimate, list) else [decimate])),
        min_speed={int(k): float(v) for k, v in c.get("min_speed", {}).items()},
    )
    ident = data.get("identification", {})
    method = str(ident.get("method", "wls")).lower()
    if method not in ("ols", "wls"):
        raise err("identification", f"method = {method!r}; use \"ols\" or \"wls\"")
    ref = data.get("reference")
    if ref is not None:
        if "file" not in ref:
            raise err("reference", "needs file = \"published.csv\"")
        ref = {**ref, "file": here / ref["file"]}
        if not ref["file"].exists():
            raise err("reference", f"file not found: {ref['file']}")
    return IdentifyConfig(
        path=path, model=model, tests=tuple(tests), channels=channels, transmission=transmission,
        conditioning=cond, method=method, known={k: float(v) for k, v in ident.get("known", {}).items()},
        poor_factor=float(ident.get("poor_factor", 20.0)), reference=ref,
    )
