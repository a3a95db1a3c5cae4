"""Mission defaults are written once: a key a mission file omits gets its dataclass's default, and
the schema comments in missions/*.yaml document those same values (so the reader, the dataclasses
and the docs cannot drift).
"""

from __future__ import annotations

import re
from dataclasses import MISSING
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from mission.adaptive.config import AdaptiveSpec
from mission.geo import afar_field
from mission.simulate import SimConfig
from mission.spec import MissionSpec, SourceSpec, VehicleSpec, parse_mission
from mission.trajectory.kinematics import Kinematics

MISSIONS = Path(__file__).resolve().parents[1] / "missions"

# every optional key with a value that is valid and differs from the default
GIVEN = {
    "altitude_m": 40.0,
    "cruise_speed_mps": 6.5,
    "time_budget_s": 900.0,
    "fence_margin_m": 5.0,
    "altitude_limits_m": [5.0, 100.0],
    "return_behaviour": "land",
    "trajectory.generator": "lawnmower",
    "source.model": "two-ray",
    "source.tx": [100.0, 80.0],
    "source.tx_height_m": 2.5,
    "source.seed": 3,
    "source.noise_db": 2.0,
    "source.attitude_perturbation_deg": 3.0,
    "source.sample_period_s": 0.05,
    "vehicle.connection": "udpin://0.0.0.0:14540",
    "vehicle.speedup": 4.0,
    "vehicle.kinematics": {"accel_mps2": 2.0},
    "adaptive.enabled": True,
    "adaptive.survey_s": 200.0,
    "adaptive.altitude_m": 40.0,
    "adaptive.radius_m": 25.0,
    "adaptive.min_radius_m": 8.0,
    "adaptive.target_area_m2": 100.0,
    "adaptive.lead_s": 20.0,
    "adaptive.update_s": 3.0,
    "adaptive.reserve_s": 10.0,
    "adaptive.explore": False,
    "adaptive.separate": True,
    "adaptive.answer_first": False,
}


def _built_in_defaults() -> dict:
    """Each key's default as the dataclasses hold it (instances built in code, not read from a
    file)."""
    m = MissionSpec(name="m", path=None, field=afar_field())
    s, v, a = SourceSpec(), VehicleSpec(), AdaptiveSpec()
    out = {
        k: getattr(m, k)
        for k in (
            "altitude_m",
            "cruise_speed_mps",
            "time_budget_s",
            "fence_margin_m",
            "altitude_limits_m",
            "return_behaviour",
        )
    }
    out["trajectory.generator"] = m.trajectory.generator
    out.update(
        {
            f"source.{k}": getattr(s, k)
            for k in (
                "model",
                "tx",
                "tx_height_m",
                "seed",
                "noise_db",
                "attitude_perturbation_deg",
                "sample_period_s",
            )
        }
    )
    out.update({f"vehicle.{k}": getattr(v, k) for k in ("connection", "speedup", "kinematics")})
    out.update(
        {
            f"adaptive.{k}": getattr(a, k)
            for k in (
                "enabled",
                "survey_s",
                "altitude_m",
                "radius_m",
                "min_radius_m",
                "target_area_m2",
                "lead_s",
                "update_s",
                "reserve_s",
                "explore",
                "separate",
                "answer_first",
            )
        }
    )
    return out


def _read(spec: MissionSpec, key: str):
    obj = spec
    for part in key.split("."):
        obj = getattr(obj, part)
    return obj


@settings(max_examples=60, deadline=None)
@given(omit=st.sets(st.sampled_from(sorted(GIVEN))))
def test_an_omitted_key_gets_the_dataclass_default(omit):
    data: dict = {}
    for key, value in GIVEN.items():
        if key not in omit:
            *head, last = key.split(".")
            d = data
            for h in head:
                d = d.setdefault(h, {})
            d[last] = value
    # the block present (possibly empty): its keys' defaults are read too
    data.setdefault("adaptive", {})
    spec = parse_mission(data, "defaults.yaml")
    default = _built_in_defaults()
    for key in GIVEN:
        got = _read(spec, key)
        want = default[key] if key in omit else GIVEN[key]
        if key == "altitude_limits_m":
            got, want = list(got), list(want)
        if key == "source.tx" and key not in omit:  # a position without z sits at tx_height_m
            want = (*GIVEN[key], spec.source.tx_height_m)
        assert got == want, key
    assert spec.source.tx_height_m == (
        default["source.tx_height_m"] if "source.tx_height_m" in omit else 2.5
    )


def test_an_empty_mission_is_the_dataclass_defaults():
    spec = parse_mission({}, "empty.yaml")
    default = _built_in_defaults()
    for key in default:
        if not key.startswith("adaptive."):
            assert _read(spec, key) == default[key] or key == "altitude_limits_m", key
    assert tuple(spec.altitude_limits_m) == default["altitude_limits_m"] and spec.adaptive is None
    # the simulated source's defaults are the simulator's own
    cfg = spec.sim_config()
    assert (cfg.dt_s, cfg.noise_db, cfg.attitude_perturbation_deg) == (
        SimConfig.dt_s,
        SimConfig.noise_db,
        SimConfig.attitude_perturbation_deg,
    )


_COMMENT = re.compile(r"^#( *)(\w+): +(\S.*?)(?: {2,}(.*))?$")


def _documented(path: Path) -> list[tuple[str, str, str, str]]:
    """(indent, key, value, description) of each schema comment line
    ``#   key: value   description``."""
    out = []
    for line in path.read_text().splitlines():
        m = _COMMENT.match(line)
        if m:
            out.append((m.group(1), m.group(2), m.group(3), m.group(4) or ""))
    return out


@pytest.mark.parametrize("name", ["spiral.yaml", "spiral_adaptive.yaml"])
def test_schema_comments_document_the_dataclass_defaults(name):
    """A value in a schema comment is the default, unless its description names another ("default:
    ...")."""
    owner = {
        "": MissionSpec,
        "source": SourceSpec,
        "vehicle": VehicleSpec,
        "adaptive": AdaptiveSpec,
    }
    block, checked = "", 0
    for indent, key, value, note in _documented(MISSIONS / name):
        if indent == " ":
            block = key if key in owner else "?"
        if key in owner and len(indent) == 1:
            continue
        cls = owner.get(block if len(indent) > 1 else "")
        if cls is None or key not in cls.__dataclass_fields__ or "default:" in note:
            continue
        if key == "kinematics":  # {accel_mps2: 1.5, ..., ...}
            for k, v in yaml.safe_load(value.replace(", ...", "")).items():
                assert getattr(Kinematics, k) == v, f"{name}: vehicle.kinematics.{k}"
                checked += 1
            continue
        v = yaml.safe_load(value)
        if isinstance(v, str) and "|" in value:
            continue  # a list of choices, not a default
        d = cls.__dataclass_fields__[key].default
        if d is MISSING:
            continue  # no plain default (the field, the home: described in words)
        if isinstance(d, tuple):
            v = tuple(v)
        assert v == d, (
            f"{name}: {block + '.' if len(indent) > 1 else ''}{key} documented {value}, default {d}"
        )
        checked += 1
    assert checked >= (10 if name == "spiral.yaml" else 8)
