"""The path generator (spec §4, block 400): one call per control tick (typically 4 ms).

tick(wrench): the force optionally low-passed (MotionParams.force_filter_hz, force_filter.py);
410/420 eps = f_des - u . F[:3] at s_des; 460/470 projected limits at s_des;
430/440 limited integral regulator; 450/500 q_des = g(s) (MOVEJF) or IK(f(s)) warm-started from
the previous setpoint (MOVELF and other Cartesian paths). The limits include, when given, joint
velocity/acceleration limits (projected through h(s) = IK(f(s)) on Cartesian paths,
joint_projection.py) and orientation-rate limits. The wrench is the robot's force on its environment (world axes).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.dynamics.force_filter import ForceFilter
from robocal.dynamics.instructions import MotionInstruction, tick_ik_options
from robocal.dynamics.joint_projection import check_position_limits, joint_derivatives
from robocal.dynamics.limits import project_limits
from robocal.dynamics.regulator import TangentialForceRegulator
from robocal.model.inverse_kinematics import solve_ik


@dataclass
class Setpoint:
    """One tick's output: q_des (nq,), s, sd 1/s, sdd 1/s^2, eps N, the limits used, and force N,
    the tangential force the regulator acted on (after the filter)."""

    q_des: np.ndarray
    s: float
    sd: float
    sdd: float
    eps: float
    sd_max: float
    sdd_max: float
    force: float = 0.0


class PathGenerator:
    """Runs one MotionInstruction. period s (4 ms by default); ik_tolerance on |log6| of the pose."""

    def __init__(self, model: pin.Model, instruction: MotionInstruction, period: float = 0.004,
                 ik_tolerance: float = 1e-10):
        self.model, self.data = model, model.createData()
        self.instruction, self.period, self.ik_tolerance = instruction, float(period), ik_tolerance
        p = instruction.params
        self.regulator = TangentialForceRegulator(p.gain if p.gain is not None else 1.0, period,
                                                  braking=p.braking and not p.blend)
        self.q_des = instruction.q_start.copy()
        self.force_filter = ForceFilter(p.force_filter_hz, period) if p.force_filter_hz is not None else None

    @property
    def s(self) -> float:
        return self.regulator.state.s

    @property
    def finished(self) -> bool:
        st = self.regulator.state
        return st.s >= 1.0 and st.sd == 0.0

    def limits(self, s: float) -> tuple[float, float]:
        """Projected (sd_max, sdd_max) at s (self.q_des is the configuration at s)."""
        ins, p = self.instruction, self.instruction.params
        _, df, ddf = ins.path.derivatives(s)
        extra = {}
        cartesian = ins.kind != "joint"
        if cartesian and p.w_max is not None:
            dw, ddw = ins.path.angular_derivatives(s)
            extra.update(dw=dw, ddw=ddw, w_max=p.w_max, dw_max=p.dw_max)
        if p.qd_max is not None:
            if cartesian:
                dw, ddw = ins.path.angular_derivatives(s)
                dh, ddh = joint_derivatives(self.model, self.data, ins.frame_id, self.q_des, df, ddf, dw, ddw)
            else:
                _, dh, ddh = ins.path.joint_derivatives(s)
            extra.update(dh=dh, ddh=ddh, qd_max=p.qd_max, qdd_max=p.qdd_max)
        return project_limits(df, ddf, p.v_max, p.a_max, p.c, **extra)

    def tick(self, wrench: np.ndarray) -> Setpoint:
        """Advance one period given the latest external wrench (6,) or force (3,) N."""
        ins, p = self.instruction, self.instruction.params
        force = np.asarray(wrench, float)[:3]
        if not np.all(np.isfinite(force)):
            raise InputError("external force signal is not finite", field="wrench")
        if self.force_filter is not None:
            force = self.force_filter.push(force)
        s = self.regulator.state.s
        _, df, ddf = ins.path.derivatives(s)
        norm_df = float(np.linalg.norm(df))
        tangential = float(df @ force) / norm_df
        eps = ins.force - tangential
        sd_max, sdd_max = self.limits(s)
        gain = p.admittance / norm_df if p.admittance is not None else p.gain
        st = self.regulator.step(eps, sd_max, sdd_max, gain)
        if ins.kind == "joint":
            self.q_des = ins.path.q_of_s(st.s)
        else:
            self.q_des = solve_ik(self.model, ins.frame_id, ins.path.pose(st.s), self.q_des, data=self.data,
                                  **tick_ik_options(self.ik_tolerance))
            check_position_limits(self.model, self.q_des, st.s)   # between the validated samples
        return Setpoint(self.q_des.copy(), st.s, st.sd, st.sdd, eps, sd_max, sdd_max, tangential)
