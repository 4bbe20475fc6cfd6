"""The physically consistent model's inertias written into the URDF's <inertial> elements.

The fit identifies composite bodies: Pinocchio merges into each moving body every link hanging from it
by fixed joints, and robocal's reduced model also the subtrees of the locked joints. The change the fit
makes to a body (identified - CAD: 10 parameters linear in the mass distribution, in the joint frame) is
added to the body's own URDF link, the joint's child link, whose frame is the joint frame; every other
link stays as written. So the written URDF, reduced to the same joints, carries exactly the identified
bodies (a test reloads it). Each edited link must remain a realisable mass distribution on its own: when
one does not (the fit took away more mass than that link has, the rest sitting in its fixed children or
locked subtrees), no URDF is written and the reason names the link. Identified viscous and Coulomb
friction go to the joints' <dynamics damping friction> (Pinocchio reads them into model.damping and
model.friction); rotor inertias and torque offsets have no URDF element and stay in result.json.
Everything else in the file is kept by lxml.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin
from lxml import etree

from robocal.dynamics.inertial import is_physically_consistent, pseudo_inertia
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


def identified_urdf(urdf_text: str, model: pin.Model, identified: np.ndarray, cad: np.ndarray,
                    friction: dict[str, dict[str, float]] | None = None) -> tuple[bytes | None, list[str]]:
    """(URDF bytes, []) with every moving body of `model` (the reduced model) carrying `identified`
    (10 per body), or (None, reasons) when an edited link would not be realisable on its own.
    cad: the model's own parameters (robocal.dynamics.inertial.parameter_vector); friction: per joint,
    {'viscous': ..., 'coulomb': ...} (either may be missing) for <dynamics>."""
    root = etree.fromstring(urdf_text.encode("utf-8"))
    joints = {j.get("name"): j for j in root.findall("joint")}
    links = {lk.get("name"): lk for lk in root.findall("link")}
    change = (np.asarray(identified, float) - np.asarray(cad, float)).reshape(-1, 10)
    reasons = []
    for j in range(1, model.njoints):
        name = model.names[j]
        child = joints[name].find("child").get("link")
        new = link_parameters(links[child]) + change[j - 1]
        if not is_physically_consistent(new):
            eig = np.linalg.eigvalsh(pseudo_inertia(new))[0]
            reasons.append(f"link '{child}' (the body of {name}) would have mass {new[0]:.4g} kg and smallest "
                           f"pseudo-inertia eigenvalue {eig:.3g} kg m^2: the fit changed that body by more than the "
                           "link itself carries (the rest hangs from it by fixed or locked joints)")
            continue
        write_inertial(links[child], new)
    if reasons:
        return None, reasons
    for name, terms in (friction or {}).items():
        write_friction(joints[name], terms.get("viscous"), terms.get("coulomb"))
    return etree.tostring(root, xml_declaration=True, encoding="utf-8"), []
