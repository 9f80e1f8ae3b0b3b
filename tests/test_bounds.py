"""Every number of the typed configs is bounded by the unit in its name (simbench.bounds)."""

from __future__ import annotations

import dataclasses
import math

import pytest
from conftest import one_line_error

from simbench.bounds import FINITE, RULES, Bound, bound_of, check_bounds
from simbench.data.log_sources import GnssLoggerConfig, LibrsfConfig, RinexConfig
from simbench.sim.config import SimConfig

#: Fields that may take any finite value on purpose.
ANY_SIGN = {"iono_alpha", "iono_beta", "constant_db"}


def numeric_fields(node: object, where: str) -> list[tuple[str, str]]:
    """(key, field name) of every int, float or numeric tuple under ``node``."""
    found = []
    for field in dataclasses.fields(node):
        value = getattr(node, field.name)
        if dataclasses.is_dataclass(value):
            found += numeric_fields(value, f"{where}.{field.name}")
        elif not isinstance(value, (bool, str)) and isinstance(value, (int, float, tuple)):
            found.append((f"{where}.{field.name}", field.name))
    return found


SIM = SimConfig()
CONFIGS = [SIM.scenario, SIM.receiver, SIM.imu, RinexConfig(), GnssLoggerConfig(), LibrsfConfig()]
FIELDS = sorted({item for config in CONFIGS for item in numeric_fields(config, type(config).__name__)})


@pytest.mark.parametrize(("key", "name"), FIELDS, ids=[key for key, _ in FIELDS])
def test_every_field_has_a_rule_of_its_unit(key: str, name: str) -> None:
    """A new field without a unit in its name would be checked only for finiteness: name its unit."""
    assert (bound_of(name) is FINITE) == (name in ANY_SIGN), f"{key}: {bound_of(name)}"


@pytest.mark.parametrize("config", CONFIGS, ids=lambda c: type(c).__name__)
def test_defaults_hold(config: object) -> None:
    check_bounds(config, "x")


def test_the_catch_all_rule_is_last_and_finite() -> None:
    assert RULES[-1] == ("", FINITE) and all(pattern for pattern, _ in RULES[:-1])


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_no_bound_holds_a_non_finite_value(value: float) -> None:
    assert not any(bound.holds(value) for _, bound in RULES)


def test_a_positive_bound_refuses_its_low_end_and_a_closed_one_keeps_it() -> None:
    assert not Bound(0.0, positive=True).holds(0.0) and Bound(0.0).holds(0.0)
    assert Bound(0.0, 1.0).holds(1.0) and not Bound(0.0, 1.0).holds(1.0 + 1e-12)


def test_message_names_the_nested_key_and_the_default() -> None:
    scenario = SimConfig().scenario
    scenario.errors.nlos.building_height_m = (40.0, 10.0)
    message = one_line_error(check_bounds, scenario, "scenario")
    assert message == (
        "scenario.errors.nlos.building_height_m: low 40 is above high 10 "
        "-- give e.g. scenario.errors.nlos.building_height_m=[10,40]"
    )


@dataclasses.dataclass
class PluginConfig:
    clock_m: float = -100.0  # a clock offset: either sign
    lon_deg: float = -79.9
    tilt_m: float = dataclasses.field(default=-2.0, metadata={"bound": Bound(-10.0, 10.0)})


def test_a_plugin_field_keeps_its_sign_or_declares_its_bound() -> None:
    config = PluginConfig()
    check_bounds(config, "scenario")
    config.tilt_m = -11.0
    assert one_line_error(check_bounds, config, "scenario").startswith("scenario.tilt_m: must be within -10 .. 10")
