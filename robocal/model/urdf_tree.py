"""The URDF's joints must form a tree, checked with lxml before Pinocchio parses the file.

urdfdom does not check it: a link that is the child of two joints makes Pinocchio build a model with a
joint twice, report a missing body, or crash the process (a segmentation fault, nothing printed), and a
cycle of joints away from the root leaves its links out of the model ("no frame ..."). robocal names the
link and its parent joints, or the joints of the loop, and says how a closed chain is written: its
spanning tree as <joint> elements, each closing joint as a <loop_joint> (robocal.model.loops_urdf).
"""
from __future__ import annotations

from pathlib import Path

from robocal.errors import InputError

#: how a closed chain is described, said with every refusal
CLOSED_CHAIN_HINT = ("a URDF is a tree, each link the child of one joint; describe a closed chain as its tree plus "
                     "a <loop_joint> per closing joint (docs/floating_nut_hexapod.md)")


def top_level_joints(tree) -> list:
    """The <joint> elements of the robot (not those inside <transmission>), in file order."""
    return [j for j in tree.iter("joint") if j.getparent() is tree]


def joint_text(j) -> str:
    return (f"'{j.get('name')}' (line {j.sourceline}: {j.find('parent').get('link')} -> "
            f"{j.find('child').get('link')})")


def check_urdf_tree(tree, path: Path) -> None:
    """Refuse a link with two parent joints and a loop of joints, naming them (parent and child links exist:
    urdf_check.check_urdf_elements ran first)."""
    parents: dict[str, list] = {}
    for j in top_level_joints(tree):
        parents.setdefault(j.find("child").get("link"), []).append(j)
    for link, joints in parents.items():
        if len(joints) < 2:
            continue
        for j in joints:
            loop = chain_back_to(link, j, parents)
            if loop:
                raise loop_error(link, loop, path)
        raise InputError(f"link '{link}' has {len(joints)} parent joints, "
                         f"{', '.join(joint_text(j) for j in joints)}: {CLOSED_CHAIN_HINT}", source=str(path),
                         field=f"link {link}")
    for link in parents:                   # every link has one parent at most: a cycle is away from the root
        loop = chain_back_to(link, parents[link][0], parents)
        if loop:
            raise loop_error(link, loop, path)


def chain_back_to(link: str, joint, parents: dict[str, list]) -> list:
    """The joints from `joint` up through first parents that lead back to `link` (a loop), else []."""
    chain, seen, up = [joint], {link}, joint.find("parent").get("link")
    while up not in seen and up in parents:
        seen.add(up)
        chain.append(parents[up][0])
        up = parents[up][0].find("parent").get("link")
    return chain if up == link else []


def loop_error(link: str, loop: list, path: Path) -> InputError:
    return InputError(f"a kinematic loop: joints {', '.join(joint_text(j) for j in reversed(loop))} lead from "
                      f"link '{link}' back to itself; {CLOSED_CHAIN_HINT}", source=str(path), field=f"link {link}")
