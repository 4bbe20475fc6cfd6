"""Every key the calibration YAML accepts, in one place, and the check that names a misspelt one.

The schema below is what the parsers read and what docs/config.md documents (a test checks that the
page mentions every key listed here, so the two cannot drift). A misspelt key anywhere - a sigma
sub-key, a `plan:` or `simulation:` setting, a key of a measurement block - is reported with its path
and the nearest valid key (difflib).
"""
from __future__ import annotations

import difflib
import inspect
from dataclasses import fields

from robocal.errors import InputError
from robocal.estimation.calibrate import CalibrationOptions
from robocal.residuals import REGISTRY

#: keys chosen by the user (joint names, parameter patterns, column names): not checked here
FREE = "free"
#: a list of measurement blocks, each checked against its type's keys
MEASUREMENTS = "measurements"

PLACEMENT = {"xyz": None, "rpy": None}
FRAME = {"name": None, "parent": None, "xyz": None, "rpy": None}
UNITS = {"length": None, "angle": None}
SIGMA = {"position": None, "orientation": None}

SCHEMA: dict = {
    "robot": {"urdf": None, "example": None, "mjcf": None, "actuated": None, "package_dirs": None, "base": PLACEMENT,
              "frames": [FRAME]},
    "data": {"csv": None, "joints": FREE, "units": UNITS, "joint_units": UNITS,
             "sessions": [{"name": None, "csv": None}], "session_column": None,
             "approach": {"from": None, "sort_by": None, "threshold": UNITS, "initial": FREE, "columns": FREE}},
    "parameters": {"preset": None, "joints": None, "frames": FREE, "base": None, "compliance": None,
                   "backlash": None, "tilt": None, "fix": None, "free": None, "initial": FREE, "priors": FREE,
                   "bounds": FREE, "per_session": None},
    "measurements": MEASUREMENTS,
    "solver": {f.name: None for f in fields(CalibrationOptions)},
    "output": {"dir": None, "report": None},
    "simulation": {"seed": None, "samples": None, "perturb": {"translation": None, "rotation": None},
                   "truth": FREE},
    "plan": {"frame": None, "N": None, "criterion": None, "seed": None, "noise": SIGMA,
             "candidates": {"method": None, "count": None, "margin": None, "levels": None, "min_singular": None,
                            "length_scale": None},
             "volume": {"box": {"min": None, "max": None},
                        "sphere": {"center": None, "max_range": None, "min_range": None}},
             "validation": None, "curve": None, "output": {"dir": None}},
    "iso9283": {"pose_id": None, "measurement": None, "commanded": None, "distance_pairs": None},
}
TOP_KEYS = tuple(SCHEMA)

#: keys of every measurement block besides its type's own settings
BLOCK_KEYS = ("type", "name", "csv", "where", "columns", "samples")
#: constructor arguments that the config fills itself (not keys a user writes)
FILLED_BY_CONFIG = ("self", "name", "samples", "measurements", "columns")
#: measurement types built from Python only: their constructors take arrays a YAML block cannot give
PYTHON_ONLY_TYPES = ("sphere_artefact", "strut_ik")
#: measurement types whose block keys are their own, not their constructor's (workflows/config_camera.py)
OWN_KEYS = {"camera": {"frame": None, "sigma": None, "attached_to": None, "mount": None, "detections": None,
                       "target": FREE, "min_corners": None, "world_pose": PLACEMENT,
                       "camera": {"model": None, "image_size": None, "intrinsics": FREE, "free": None,
                                  "prior": FREE}}}


def measurement_keys(type_name: str) -> dict:
    """The keys a block of this measurement type accepts: the shared ones and its constructor's (or its own)."""
    if type_name in OWN_KEYS:
        shared = {k: None for k in BLOCK_KEYS if k not in ("columns", "samples")}
        return {**shared, **OWN_KEYS[type_name], "where": FREE}
    cls = REGISTRY[type_name]
    own = [p for p in inspect.signature(cls.__init__).parameters if p not in FILLED_BY_CONFIG]
    return {**{k: None for k in BLOCK_KEYS}, **{k: (SIGMA if k == "sigma" else None) for k in own},
            "where": FREE}


def all_key_names() -> set[str]:
    """Every literal key name of the schema and of every measurement type (for the docs test)."""
    names: set[str] = set()

    def walk(schema):
        if isinstance(schema, list):
            walk(schema[0])
        elif isinstance(schema, dict):
            for k, v in schema.items():
                names.add(k)
                walk(v)
    walk(SCHEMA)
    for t in REGISTRY:
        if t not in PYTHON_ONLY_TYPES:
            walk(measurement_keys(t))
    return names


def unknown_key_error(key, allowed, path: str, source: str) -> InputError:
    close = difflib.get_close_matches(str(key), [str(a) for a in allowed], n=1, cutoff=0.5)
    hint = f" (did you mean '{close[0]}'?)" if close else f" (allowed: {', '.join(map(str, allowed))})"
    return InputError(f"unknown key{hint}", source=source, field=f"{path}.{key}" if path else str(key))


def check_keys(raw, source: str, schema=None, path: str = "") -> None:
    """Raise InputError on the first key of `raw` the schema does not know, anywhere in the document.

    Only names are checked here; types and values are checked by the parsers that read them.
    """
    schema = SCHEMA if schema is None else schema
    if schema is None or schema == FREE:
        return
    if schema == MEASUREMENTS:
        for i, block in enumerate(raw if isinstance(raw, list) else []):
            if isinstance(block, dict) and block.get("type") in REGISTRY and block["type"] not in PYTHON_ONLY_TYPES:
                check_keys(block, source, measurement_keys(block["type"]), f"{path}[{i}]")
        return
    if isinstance(schema, list):
        for i, item in enumerate(raw if isinstance(raw, list) else []):
            check_keys(item, source, schema[0], f"{path}[{i}]")
        return
    if not isinstance(raw, dict):
        return
    for key, value in raw.items():
        if key not in schema:
            raise unknown_key_error(key, list(schema), path, source)
        check_keys(value, source, schema[key], f"{path}.{key}" if path else str(key))


class Cfg:
    """A mapping from the YAML with its key path, for error messages that say where."""

    def __init__(self, value, path: str, source: str):
        self.value, self.path, self.source = value, path, source

    def where(self, key: str | None = None) -> str | None:
        return (f"{self.path}.{key}" if key and self.path else (key or self.path)) or None

    def error(self, msg: str, key: str | None = None) -> InputError:
        return InputError(msg, source=self.source, field=self.where(key))

    def require_mapping(self) -> "Cfg":
        if not isinstance(self.value, dict):
            raise self.error(f"expected a mapping, got {type(self.value).__name__}")
        return self

    def check_keys(self, allowed) -> None:
        self.require_mapping()
        for k in self.value:
            if k not in allowed:
                raise unknown_key_error(k, list(allowed), self.path, self.source)

    def get(self, key: str, default=None, required: bool = False, types=None):
        self.require_mapping()
        if key not in self.value:
            if required:
                raise self.error("required key is missing", key)
            return default
        v = self.value[key]
        if types is not None and (not isinstance(v, types) or (isinstance(v, bool) and bool not in _tuple(types))):
            names = types.__name__ if isinstance(types, type) else "/".join(t.__name__ for t in types)
            raise self.error(f"expected {names}, got {type(v).__name__} ({v!r})", key)
        return v

    def number(self, key: str, default: float, positive: bool = False) -> float:
        """A finite number (a positive one with positive=True)."""
        v = float(self.get(key, default, types=(int, float)))
        if not (v == v and abs(v) != float("inf")) or (positive and not v > 0):
            raise self.error(f"expected a {'positive ' if positive else ''}finite number, got {v!r}", key)
        return v

    def child(self, key: str, default=None) -> "Cfg":
        return Cfg(self.value.get(key, default) if isinstance(self.value, dict) else default,
                   f"{self.path}.{key}" if self.path else key, self.source)


def _tuple(types) -> tuple:
    return types if isinstance(types, tuple) else (types,)
