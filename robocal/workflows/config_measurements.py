"""A measurement block of the calibration config -> its residual class, its sigma, and the residual it builds.

Units rule (docs/config.md, "Units"): measurement columns are in `data.units`, and so is a block's
`sigma` - a length sigma in the length unit, an angle sigma in the angle unit - unless it is written
with its unit ("0.05 mm", "0.1 deg", "20 um", "0.5 mrad").
"""
from __future__ import annotations

import inspect
import re

import numpy as np

from robocal.errors import InputError
from robocal.workflows.config_keys import PYTHON_ONLY_TYPES, Cfg
from robocal.workflows.config_types import MeasurementConfig, Units
from robocal.io.tables import ANGLE_UNITS, LENGTH_UNITS, Table
from robocal.residuals import REGISTRY

#: units a sigma may be labelled with, in SI, and the quantity each measures
SIGMA_LABELS = {**{u: (f, "length") for u, f in LENGTH_UNITS.items()}, "um": (1e-6, "length"),
                **{u: (f, "angle") for u, f in ANGLE_UNITS.items()}, "mrad": (1e-3, "angle"),
                "urad": (1e-6, "angle")}
_LABELLED = re.compile(r"^\s*([-+0-9.eE]+)\s*([a-z]+)\s*$")
_NUMBER = re.compile(r"^\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*$")


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


def sigma_value(value, node: Cfg, key: str, units: Units, kinds: frozenset[str] | None = None) -> float:
    """One sigma in data units: a positive finite number, or a labelled string converted to data units.

    kinds: the row kinds ('length', 'angle') the sigma applies to; a labelled sigma must measure the same
    quantity (a position sigma in deg is refused), and an angle sigma beyond pi rad is no standard deviation."""
    if isinstance(value, str) and _NUMBER.match(value):
        value = float(value)          # YAML 1.1 reads 1e-5 (no dot) as text
    kind = None
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
        if kinds is not None and kinds != {kind}:
            raise node.error(sigma_kind_mismatch(value, kind, kinds, key), key)
        si_unit = LENGTH_UNITS if kind == "length" else ANGLE_UNITS
        value = number * factor / si_unit[getattr(units, kind)]
    elif isinstance(value, bool) or not isinstance(value, (int, float)):
        raise node.error(f"expected a number, got {type(value).__name__} ({value!r})", key)
    if not (np.isfinite(value) and value > 0):
        raise node.error(f"a sigma must be a positive number (and finite), got {value!r}", key)
    if (kind == "angle" or kinds == {"angle"}) and value * ANGLE_UNITS[units.angle] > np.pi:
        raise node.error(f"a sigma of {value:g} {units.angle} is beyond half a turn: no angle measurement errs by "
                         "that much (a sigma is the measurement's standard deviation; check the value and its unit)",
                         key)
    return float(value)


def sigma_kind_mismatch(text: str, kind: str, kinds: frozenset[str], key: str) -> str:
    """Why a labelled sigma does not fit the rows it applies to, and what to write instead."""
    if len(kinds) > 1:
        return (f"{text!r} is {'a length' if kind == 'length' else 'an angle'}, but this block's rows are lengths "
                "and angles: give each its own, sigma: {position: <length>, orientation: <angle>}")
    want = next(iter(kinds))
    what = f"'{key}'" if key in ("position", "orientation") else "this block's rows"
    return (f"{text!r} is {'a length' if kind == 'length' else 'an angle'}, but {what} "
            f"{'measure' if what.startswith('this') else 'measures'} {'lengths' if want == 'length' else 'angles'}"
            f": write it in {', '.join(u for u, (_, k) in SIGMA_LABELS.items() if k == want)}")


#: the kind of a pose block's two sigmas
SIGMA_KEY_KINDS = {"position": frozenset({"length"}), "orientation": frozenset({"angle"})}


def sigma_argument(raw, node: Cfg, units: Units, kinds: frozenset[str] | None = None):
    """A block's `sigma` in data units: a number (or labelled string), or a mapping -> (position, orientation).
    kinds: the block's row kinds (row_kinds), which a labelled scalar sigma must match."""
    if isinstance(raw, dict):
        sub = node.child("sigma")
        return tuple(sigma_value(raw.get(k, 1e-4), sub, k, units, SIGMA_KEY_KINDS[k])
                     for k in ("position", "orientation"))
    return sigma_value(raw, node, "sigma", units, kinds)


def row_kinds(cls) -> frozenset[str] | None:
    """The quantities ('length', 'angle') a measurement type's rows hold; types whose rows are sized per block
    (rigid_points: 3 per point) declare row_units as a property, read on a one-row stand-in."""
    units = inspect.getattr_static(cls, "row_units", None)
    if isinstance(units, property):
        try:
            units = units.fget(_OneRow())
        except (AttributeError, TypeError):
            return None
    return frozenset(units) if isinstance(units, tuple) else None


class _OneRow:
    """What a sized type's row_units property reads (dim, the struts' count): one row."""
    dim = 1
    struts = (None,)


def accepts_measurements(cls) -> bool:
    """Whether a measurement type reads columns of measured values (pose, point, ...) or only contacts."""
    return "measurements" in inspect.signature(cls.__init__).parameters


def residual_from_block(cls, block: MeasurementConfig, source: str, parts: list[tuple[Table, np.ndarray]],
                        sample_idx, units: Units, sigma=None):
    """The residual of one block of the config `source` over the rows it reads: parts, (table, rows) in order
    (one per session file); sigma (optional, data units) replaces the block's own (robocal plan's noise)."""
    kwargs = dict(block.settings)
    sigma = block.sigma if sigma is None else sigma
    if sigma is not None:
        kwargs["sigma"] = sigma
    if accepts_measurements(cls):
        kinds = cls.column_kinds(len(block.columns))
        kwargs["measurements"] = np.vstack([
            np.column_stack([tab.column(c, k, getattr(units, k) if k else None, rows)
                             for c, k in zip(block.columns, kinds)]) for tab, rows in parts])
        kwargs["columns"] = list(block.columns)
    try:
        res = cls(name=block.name, frame=block.frame, samples=sample_idx, **kwargs)
    except (TypeError, ValueError) as exc:
        key = getattr(exc, "field", None)          # a residual's InputError names its argument (weights, sigma)
        raise InputError(getattr(exc, "reason", str(exc)), source=source,
                         field=f"{block.path}.{key}" if key else block.path) from None
    if sigma is not None:
        # the sigma numbers are in data units: each row to SI by its quantity
        scale = {"length": LENGTH_UNITS[units.length], "angle": ANGLE_UNITS[units.angle]}
        res.sigma = res.sigma * np.array([scale.get(u, 1.0) for u in res.row_units])
    return res
