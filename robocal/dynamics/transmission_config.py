"""The `transmission:` section of an identification config, checked and turned into a Transmission.

Two forms of the motor-to-joint map q = T m + c (transmission.py):
  motors: {motor: joint it drives}, ratio: {motor: motor rad per joint rad (or per m)}, coupling: {joint:
      {motor: joint rad per motor rad}}: T[joint(motor), motor] = 1 / ratio, plus the coupling entries;
  motors: [names] or {motor: joint}, matrix: {joint: {motor: value}} or a list of rows (robot.joints order,
      columns in motors order): T itself.
offset: {joint: c}; effort: current (default) or torque: what the logs' effort columns hold; motor_constant:
{motor: N m/A}, required for every logged motor when the efforts are currents. Every error names the config file
and the key (transmission.coupling.wrist_3_joint.motor_9). See docs/dynamics_motors.md.
"""
from __future__ import annotations

import numpy as np

from robocal.dynamics.transmission import EFFORT_KINDS, Transmission
from robocal.errors import InputError

KEYS = ("motors", "ratio", "coupling", "matrix", "offset", "effort", "motor_constant")


def transmission_from_config(raw, joints: list[str], logged: list[str] | None, source: str) -> Transmission:
    """raw: the section's mapping; joints: robot.joints (the rows, in this order); logged: the motors whose
    efforts the logs hold (effort.recorded; None: every motor)."""
    def error(msg, key=None):
        return InputError(msg, source=source, field="transmission" + (f".{key}" if key else ""))

    if not isinstance(raw, dict):
        raise error(f"expected a mapping, got {type(raw).__name__}")
    for key in raw:
        if key not in KEYS:
            raise error(f"unknown key '{key}'; known: {', '.join(KEYS)}", key)
    motors, drives = _motors(raw.get("motors"), joints, error)
    if ("matrix" in raw) == ("ratio" in raw):
        raise error("give either ratio (with coupling) or matrix", "matrix")
    if "matrix" in raw:
        if "coupling" in raw:
            raise error("coupling goes with ratio; with matrix, write the coupling entries in the matrix", "coupling")
        matrix = _matrix(raw["matrix"], joints, motors, error)
    else:
        if drives is None:
            raise error("ratio needs motors as a mapping {motor: the joint it drives}", "motors")
        matrix = np.zeros((len(joints), len(motors)))
        ratio = _numbers(raw["ratio"], motors, "ratio", error, nonzero=True, every=True)
        for k, m in enumerate(motors):
            matrix[joints.index(drives[m]), k] = 1.0 / ratio[m]
        for joint, entries in _mapping(raw.get("coupling", {}), "coupling", error).items():
            if joint not in joints:
                raise error(f"'{joint}' is not one of robot.joints ({', '.join(joints)})", f"coupling.{joint}")
            for m, value in _numbers(entries, motors, f"coupling.{joint}", error).items():
                if drives[m] == joint:
                    raise error(f"'{m}' drives '{joint}' already (its ratio): a coupling entry is another joint's",
                                f"coupling.{joint}.{m}")
                matrix[joints.index(joint), motors.index(m)] = value
    offset = _numbers(raw.get("offset", {}), joints, "offset", error)
    kind = raw.get("effort", "current")
    if kind not in EFFORT_KINDS:
        raise error(f"expected one of {', '.join(EFFORT_KINDS)}, got {kind!r}", "effort")
    logged = list(motors) if logged is None else logged
    for m in logged:
        if m not in motors:
            raise InputError(f"'{m}' is not one of transmission.motors ({', '.join(motors)})", source=source,
                             field="effort.recorded")
    if kind == "torque":
        if "motor_constant" in raw:
            raise error("the efforts are motor torques (effort: torque): no torque constant applies", "motor_constant")
        constants = None
    else:
        if "motor_constant" not in raw:
            raise error("the efforts are currents (effort: current): a torque constant (N m/A) per logged motor is "
                        "needed to make them torques (or say effort: torque)", "motor_constant")
        given = _numbers(raw["motor_constant"], motors, "motor_constant", error, nonzero=True)
        missing = [m for m in logged if m not in given]
        if missing:
            raise error(f"currents without a torque constant for {', '.join(missing)}", "motor_constant")
        constants = np.array([given.get(m, np.nan) for m in motors])
    return Transmission(list(joints), motors, matrix, np.array([offset.get(j, 0.0) for j in joints]), constants,
                        source)


def _motors(value, joints, error):
    """(motor names, {motor: joint} or None)."""
    if isinstance(value, list):
        if not value or not all(isinstance(m, str) for m in value):
            raise error("expected a non-empty list of motor names or a mapping {motor: joint}", "motors")
        return list(value), None
    drives = _mapping(value, "motors", error)
    if not drives:
        raise error("expected a non-empty list of motor names or a mapping {motor: joint}", "motors")
    for m, j in drives.items():
        if j not in joints:
            raise error(f"'{j}' is not one of robot.joints ({', '.join(joints)})", f"motors.{m}")
    driven = list(drives.values())
    twice = sorted({j for j in driven if driven.count(j) > 1})
    if twice:
        raise error(f"{', '.join(twice)} driven by more than one motor here: map each motor to the joint it "
                    "drives and write the others' share as coupling", "motors")
    return [str(m) for m in drives], {str(m): j for m, j in drives.items()}


def _matrix(value, joints, motors, error) -> np.ndarray:
    n = len(joints)
    if isinstance(value, list):
        if len(value) != n or not all(isinstance(r, list) and len(r) == len(motors) for r in value):
            raise error(f"expected {n} rows (robot.joints) of {len(motors)} numbers (motors)", "matrix")
        try:
            return np.array(value, float)
        except (TypeError, ValueError):
            raise error("every entry must be a number", "matrix") from None
    matrix = np.zeros((n, len(motors)))
    for joint, entries in _mapping(value, "matrix", error).items():
        if joint not in joints:
            raise error(f"'{joint}' is not one of robot.joints ({', '.join(joints)})", f"matrix.{joint}")
        for m, v in _numbers(entries, motors, f"matrix.{joint}", error).items():
            matrix[joints.index(joint), motors.index(m)] = v
    return matrix


def _mapping(value, key, error) -> dict:
    if not isinstance(value, dict):
        raise error(f"expected a mapping, got {type(value).__name__}", key)
    return value


def _numbers(value, names, key, error, nonzero=False, every=False) -> dict[str, float]:
    """{name: finite number} with every name one of `names` (all of them with every=True)."""
    out = {}
    for name, v in _mapping(value, key, error).items():
        if name not in names:
            raise error(f"'{name}' is not one of {', '.join(names)}", f"{key}.{name}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or (nonzero and v == 0):
            raise error(f"expected a {'non-zero ' if nonzero else ''}finite number, got {v!r}", f"{key}.{name}")
        out[str(name)] = float(v)
    if every:
        missing = [n for n in names if n not in out]
        if missing:
            raise error(f"missing for {', '.join(missing)}", key)
    return out
