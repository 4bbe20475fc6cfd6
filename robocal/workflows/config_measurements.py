"""A measurement block of the calibration YAML -> a residual, with its columns and sigma in SI.

Units rule (docs/config.md, "Units"): measurement columns are in `data.units`, and so is a block's
`sigma` - a length sigma in the length unit, an angle sigma in the angle unit - unless it is written
with its unit ("0.05 mm", "0.1 deg", "20 um", "0.5 mrad").
"""
from __future__ import annotations

import inspect
import re

import numpy as np

from robocal.workflows.config_keys import FILLED_BY_CONFIG, PYTHON_ONLY_TYPES, Cfg
from robocal.io.tables import ANGLE_UNITS, LENGTH_UNITS, Table
from robocal.residuals import REGISTRY

#: units a sigma may be labelled with, in SI, and the quantity each measures
SIGMA_LABELS = {**{u: (f, "length") for u, f in LENGTH_UNITS.items()}, "um": (1e-6, "length"),
                **{u: (f, "angle") for u, f in ANGLE_UNITS.items()}, "mrad": (1e-3, "angle"),
                "urad": (1e-6, "angle")}
_LABELLED = re.compile(r"^\s*([-+0-9.eE]+)\s*([a-z]+)\s*$")


def residual_class(block: Cfg):
    """The residual class a block's `type` names (InputError naming the key otherwise)."""
    res_type = block.get("type", required=True, types=str)
    if res_type not in REGISTRY:
        raise block.error(f"unknown measurement type '{res_type}' (known: {', '.join(sorted(REGISTRY))}; "
                          f"docs/config.md lists them)", "type")
    if res_type in PYTHON_ONLY_TYPES:
        raise block.error(f"'{res_type}' blocks are built from Python ({REGISTRY[res_type].__name__}), not "
                          f"from a config file (docs/config.md)", "type")
    return REGISTRY[res_type]


def sigma_value(value, node: Cfg, key: str, units: dict[str, str]) -> float:
    """One sigma in data units: a positive number, or a labelled string converted to data units."""
    if isinstance(value, str):
        m = _LABELLED.match(value)
        if not m or m.group(2) not in SIGMA_LABELS:
            raise node.error(f"expected a number or a number with a unit ({', '.join(SIGMA_LABELS)}), "
                             f"got {value!r}", key)
        try:
            number = float(m.group(1))
        except ValueError:
            raise node.error(f"'{m.group(1)}' is not a number", key) from None
        factor, kind = SIGMA_LABELS[m.group(2)]
        si_unit = LENGTH_UNITS if kind == "length" else ANGLE_UNITS
        value = number * factor / si_unit[units[kind]]
    elif isinstance(value, bool) or not isinstance(value, (int, float)):
        raise node.error(f"expected a number, got {type(value).__name__} ({value!r})", key)
    if not (np.isfinite(value) and value > 0):
        raise node.error(f"a sigma must be a positive number, got {value!r}", key)
    return float(value)


def sigma_argument(raw, node: Cfg, units: dict[str, str]):
    """The constructor's sigma (in data units) of a block's `sigma` (number, labelled string or mapping)."""
    if isinstance(raw, dict):
        sub = node.child("sigma")
        return tuple(sigma_value(raw.get(k, 1e-4), sub, k, units) for k in ("position", "orientation"))
    return sigma_value(raw, node, "sigma", units)


def residual_from_block(cls, block: Cfg, tab: Table, rows, sample_idx, units: dict[str, str], sigma=None):
    """The residual of one block; sigma (optional) replaces the block's own (robocal plan's noise)."""
    reserved = ("type", "csv", "where", "columns", "samples")   # samples: used by `robocal simulate` only
    kwargs = {k: v for k, v in block.value.items() if k not in reserved and k not in FILLED_BY_CONFIG}
    name = block.get("name", f"{block.value['type']}{block.path[block.path.index('[') + 1:-1]}", types=str)
    if sigma is not None:
        kwargs["sigma"] = sigma_argument(sigma, Cfg({"sigma": sigma}, "plan.noise", block.source), units)
    elif "sigma" in kwargs:
        kwargs["sigma"] = sigma_argument(kwargs["sigma"], block, units)
    accepts_measurements = "measurements" in inspect.signature(cls.__init__).parameters
    if accepts_measurements:
        columns = block.get("columns", required=True, types=list)
        kinds = cls.column_kinds(len(columns))
        if len(kinds) != len(columns):
            raise block.error(f"{cls.type_name} needs {len(kinds)} columns, got {len(columns)}", "columns")
        data = [tab.column(str(c), k, units[k] if k else None, rows) for c, k in zip(columns, kinds)]
        kwargs["measurements"] = np.column_stack(data)
        kwargs["columns"] = [str(c) for c in columns]
    try:
        res = cls(name=name, samples=sample_idx, **kwargs)
    except (TypeError, ValueError) as exc:
        raise block.error(getattr(exc, "reason", str(exc))) from None
    if "sigma" in kwargs or sigma is not None:
        # the sigma numbers are in data units: each row to SI by its quantity
        scale = {"length": LENGTH_UNITS[units["length"]], "angle": ANGLE_UNITS[units["angle"]]}
        res.sigma = res.sigma * np.array([scale.get(u, 1.0) for u in res.row_units])
    return res
