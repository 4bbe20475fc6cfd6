"""The physically consistent model's inertias written into the URDF's <inertial> elements.

The fit identifies composite bodies: Pinocchio merges into each moving body every link hanging from it
by fixed joints, and robocal's reduced model also the subtrees of the locked joints. The change the fit
makes to a body (identified - CAD: 10 parameters linear in the mass distribution, in the joint frame) is
shared among the URDF links merged into that body (its own link, the links fixed to it, the locked
subtrees) in proportion to their CAD masses, each share moved into its link's frame (the pseudo-inertia
transforms as A J A^T). The shares add up to the change, so the written URDF, reduced to the same joints,
carries exactly the identified bodies (a test reloads it). When a share would leave a link unrealisable on
its own (the change takes away more than that link carries, e.g. a lighter composite body whose CAD
links differ in shape), that body's links are written instead as the identified body scaled by their
CAD mass shares (each realisable since the body is; exact for the reduced model, but each link then has
the body's shape): a remark names the body. Identified viscous and Coulomb
friction go to the joints' <dynamics damping friction> (Pinocchio reads them into model.damping and
model.friction); rotor inertias, offsets, springs, asymmetric friction and delays have no URDF element and go to the side
file (identified_model.py).
Everything else in the file is kept by lxml.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin
from lxml import etree

from robocal.dynamics.inertial import is_physically_consistent, params_from_pseudo_inertia, pseudo_inertia
from robocal.io.text_files import format_number, format_numbers

INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


def link_parameters(link_el) -> np.ndarray:
    """The 10 inertial parameters of a URDF <link> in its own frame (zeros without <inertial>)."""
    inertial = link_el.find("inertial")
    if inertial is None:
        return np.zeros(10)
    mass_el, origin, inertia_el = inertial.find("mass"), inertial.find("origin"), inertial.find("inertia")
    mass = float(mass_el.get("value")) if mass_el is not None else 0.0
    xyz = np.array([float(v) for v in ((origin.get("xyz") if origin is not None else None) or "0 0 0").split()])
    rpy = np.array([float(v) for v in ((origin.get("rpy") if origin is not None else None) or "0 0 0").split()])
    i = {k: float(inertia_el.get(k, 0.0)) if inertia_el is not None else 0.0 for k in INERTIA_KEYS}
    about_com = np.array([[i["ixx"], i["ixy"], i["ixz"]], [i["ixy"], i["iyy"], i["iyz"]],
                          [i["ixz"], i["iyz"], i["izz"]]])
    R = pin.rpy.rpyToMatrix(*rpy)
    return pin.Inertia(mass, xyz, R @ about_com @ R.T).toDynamicParameters()


def write_inertial(link_el, params10: np.ndarray) -> None:
    """Replace the link's <inertial> by the body `params10` (centre of mass as origin, axes of the link)."""
    body = pin.Inertia.FromDynamicParameters(np.asarray(params10, float))
    old = link_el.find("inertial")
    inertial = etree.Element("inertial")
    if old is not None:
        inertial.tail = old.tail
        link_el.replace(old, inertial)
    else:
        link_el.insert(0, inertial)
    etree.SubElement(inertial, "origin", xyz=format_numbers(body.lever), rpy="0 0 0")
    etree.SubElement(inertial, "mass", value=format_number(body.mass))
    I = body.inertia
    etree.SubElement(inertial, "inertia", **{k: format_number(I[a, b]) for k, (a, b) in zip(
        INERTIA_KEYS, ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)))})


def write_friction(joint_el, viscous: float | None, coulomb: float | None) -> None:
    """Set the joint's <dynamics damping="viscous" friction="coulomb"/>, keeping what is not given."""
    dyn = joint_el.find("dynamics")
    if dyn is None:
        dyn = etree.SubElement(joint_el, "dynamics")
    if viscous is not None:
        dyn.set("damping", format_number(viscous))
    if coulomb is not None:
        dyn.set("friction", format_number(coulomb))


def to_link_frame(params10: np.ndarray, placement: pin.SE3) -> np.ndarray:
    """10 parameters about a joint frame re-expressed in a link frame placed at `placement` in it (linear:
    any values, realisable or not)."""
    A = np.eye(4)
    A[:3, :3] = placement.rotation.T
    A[:3, 3] = -placement.rotation.T @ placement.translation
    return params_from_pseudo_inertia(A @ pseudo_inertia(params10) @ A.T)


def identified_urdf(urdf_text: str, model: pin.Model, identified: np.ndarray, cad: np.ndarray,
                    friction: dict[str, dict[str, float]] | None = None) -> tuple[bytes, list[str]]:
    """(URDF bytes, remarks) with every moving body of `model` (the reduced model) carrying `identified`
    (10 per body, each realisable); remarks name the bodies written as scaled copies (module docstring).
    cad: the model's own parameters (robocal.dynamics.inertial.parameter_vector); friction: per joint,
    {'viscous': ..., 'coulomb': ...} (either may be missing) for <dynamics>."""
    root = etree.fromstring(urdf_text.encode("utf-8"))
    joints = {j.get("name"): j for j in root.findall("joint")}
    links = {lk.get("name"): lk for lk in root.findall("link")}
    change = (np.asarray(identified, float) - np.asarray(cad, float)).reshape(-1, 10)
    remarks = []
    for j in range(1, model.njoints):
        name = model.names[j]
        shares = [(f.name, f.placement) for f in model.frames
                  if f.parentJoint == j and f.type == pin.FrameType.BODY and f.name in links]
        masses = {n: link_parameters(links[n])[0] for n, _ in shares}
        total = sum(masses.values())
        child = joints[name].find("child").get("link")
        weights = {n: (masses[n] / total if total > 0 else float(n == child)) for n, _ in shares}
        added = {n: link_parameters(links[n]) + weights[n] * to_link_frame(change[j - 1], pl) for n, pl in shares
                 if weights[n] > 0}
        if np.any(change[j - 1]) and not all(is_physically_consistent(p) for p in added.values()):
            body = np.asarray(identified, float).reshape(-1, 10)[j - 1]
            added = {n: weights[n] * to_link_frame(body, pl) for n, pl in shares if weights[n] > 0}
            remarks.append(f"the body of {name}: its change would leave a link unrealisable, so its {len(added)} "
                           "links carry the identified body scaled by their CAD mass shares")
        for link, params in added.items():
            write_inertial(links[link], params)
    for name, terms in (friction or {}).items():
        write_friction(joints[name], terms.get("viscous"), terms.get("coulomb"))
    return etree.tostring(root, xml_declaration=True, encoding="utf-8"), remarks
