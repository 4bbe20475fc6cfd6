"""What a URDF's inertials say before any fit: non-finite values refused, inconsistent or massless links noted.

A NaN or infinite mass, centre of mass or inertia is refused with the link named (it would otherwise run
the whole identification and fail while writing). A link whose inertia is not a mass distribution
(pseudo-inertia not PSD, e.g. Ixx + Iyy < Izz) and a moving body whose CAD mass is zero are usable, and
noted: the first as a CAD value the consistent fit cannot stay at, the second as a body with no mass band
(plausible_bounds.py), identified from the data alone.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin
from lxml import etree

from robocal.dynamics.inertial import pseudo_inertia
from robocal.dynamics.plausible_bounds import ZERO_MASS
from robocal.dynamics.urdf_inertials import INERTIA_KEYS
from robocal.errors import InputError


def check_urdf_inertials(urdf_text: str, source: str, noted: set[str] | None = None) -> list[str]:
    """Raise InputError for a non-finite inertial value; notes for links whose inertia is not realisable
    (only those in `noted`, the links of the moving bodies, when given)."""
    root = etree.fromstring(urdf_text.encode("utf-8"))
    notes = []
    for link in root.findall("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        name = link.get("name")
        values = {}
        for tag, keys in (("mass", ("value",)), ("inertia", INERTIA_KEYS), ("origin", ("xyz", "rpy"))):
            el = inertial.find(tag)
            for k in keys:
                raw = el.get(k) if el is not None else None
                if raw is None:
                    continue
                try:
                    numbers = [float(x) for x in raw.split()]
                except ValueError:
                    raise InputError(f"link '{name}': {tag} {k}='{raw}' is not a number", source=source,
                                     field=f"link {name}/inertial/{tag}@{k}") from None
                if not np.all(np.isfinite(numbers)):
                    raise InputError(f"link '{name}': {tag} {k}='{raw}' is not finite", source=source,
                                     field=f"link {name}/inertial/{tag}@{k}")
                values[(tag, k)] = numbers
        mass = values.get(("mass", "value"), [0.0])[0]
        if mass < 0:
            raise InputError(f"link '{name}' has negative mass {mass}", source=source,
                             field=f"link {name}/inertial/mass@value")
        i = {k: values.get(("inertia", k), [0.0])[0] for k in INERTIA_KEYS}
        about_com = np.array([[i["ixx"], i["ixy"], i["ixz"]], [i["ixy"], i["iyy"], i["iyz"]],
                              [i["ixz"], i["iyz"], i["izz"]]])
        params = pin.Inertia(max(mass, 0.0), np.zeros(3), about_com).toDynamicParameters()
        eig = np.linalg.eigvalsh(pseudo_inertia(params))
        if eig[0] < -1e-9 * max(abs(eig[-1]), 1e-12) and (noted is None or name in noted):
            notes.append(f"the URDF's link '{name}' is not a mass distribution (smallest pseudo-inertia eigenvalue "
                         f"{eig[0]:.3g} kg m^2: its inertia breaks the triangle inequality); the consistent fit "
                         "cannot keep that CAD value")
    return notes


def moving_links(model: pin.Model) -> set[str]:
    """The URDF links merged into the reduced model's moving bodies."""
    return {f.name for f in model.frames if f.parentJoint > 0 and f.type == pin.FrameType.BODY}


def massless_body_notes(model: pin.Model) -> list[str]:
    return [f"the body of {model.names[j]} has CAD mass {model.inertias[j].mass:.3g} kg: no mass band, its mass "
            "comes from the data alone" for j in range(1, model.njoints) if model.inertias[j].mass <= ZERO_MASS]
