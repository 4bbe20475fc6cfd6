"""Force/torque-sensor variant of the force signal (spec §2.4 item 1, §11.2 item 6).

A wrist sensor reads the wrench the tool side exerts beyond it, in the sensor frame, about its
origin. After offset and gain correction and removal of the tool's weight (the part of the reading
the tool's own gravity causes), the reading is moved to world-aligned axes at the TCP with
SE3.act on pin.Force, so it can replace the current-based estimate unchanged.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.errors import InputError

GRAVITY = np.array([0.0, 0.0, -9.81])


class ForceSensorSource:
    """model, sensor_frame, tcp_frame (frame ids); offset (6,) and gain (6,) of the raw reading
    (wrench = gain * (raw - offset)); tool_mass kg and tool_com (3,) m in the sensor frame, for
    the part of the tool hanging beyond the sensor."""

    def __init__(self, model: pin.Model, sensor_frame: int, tcp_frame: int, offset=None, gain=None,
                 tool_mass: float = 0.0, tool_com=None):
        self.model, self.data = model, model.createData()
        self.sensor_frame, self.tcp_frame = sensor_frame, tcp_frame
        self.offset = np.zeros(6) if offset is None else np.asarray(offset, float)
        self.gain = np.ones(6) if gain is None else np.asarray(gain, float)
        if self.offset.shape != (6,) or self.gain.shape != (6,) or np.any(self.gain == 0):
            raise InputError("sensor offset and gain must be 6 numbers (gain non-zero)", field="gain")
        self.tool_mass = float(tool_mass)
        self.tool_com = np.zeros(3) if tool_com is None else np.asarray(tool_com, float)

    def wrench_at_tcp(self, q: np.ndarray, raw: np.ndarray) -> np.ndarray:
        """Robot-on-environment wrench (6,) [N, N m] in world axes about the TCP from a raw reading."""
        m, d = self.model, self.data
        pin.framesForwardKinematics(m, d, q)
        oMs, oMt = d.oMf[self.sensor_frame], d.oMf[self.tcp_frame]
        reading = self.gain * (np.asarray(raw, float) - self.offset)
        # the tool's weight pulls on the sensor too: remove it (sensor frame, about the sensor origin)
        weight = oMs.rotation.T @ (self.tool_mass * GRAVITY)
        reading = reading - np.r_[weight, np.cross(self.tool_com, weight)]
        lwa_tcp = pin.SE3(np.eye(3), oMt.translation)
        return lwa_tcp.actInv(oMs.act(pin.Force(reading))).vector

    def raw_from_wrench(self, q: np.ndarray, wrench_at_tcp: np.ndarray) -> np.ndarray:
        """The raw reading a given TCP wrench produces (for synthesising sensor data)."""
        m, d = self.model, self.data
        pin.framesForwardKinematics(m, d, q)
        oMs, oMt = d.oMf[self.sensor_frame], d.oMf[self.tcp_frame]
        lwa_tcp = pin.SE3(np.eye(3), oMt.translation)
        reading = oMs.actInv(lwa_tcp.act(pin.Force(np.asarray(wrench_at_tcp, float)))).vector
        weight = oMs.rotation.T @ (self.tool_mass * GRAVITY)
        reading = reading + np.r_[weight, np.cross(self.tool_com, weight)]
        return reading / self.gain + self.offset
