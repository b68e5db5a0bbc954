"""URDF files read into robot models (:mod:`armlab.kinematics.model`): a serial chain from
the file's root to a tip link, or a quadruped's four legs.

Frames: a chain's *base frame* is the link the first movable joint hangs from.
Fixed joints before it are folded into ``base_pose`` (world <- base); fixed
joints between movable ones are folded into the next joint's origin; fixed
joints after the last one form ``tip`` (last link <- end effector). Masses of
links on fixed joints are lumped into the moving link they ride on.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from armlab.kinematics.model import Capsule, Joint, Link, Quadruped, SerialChain, URDFError
from armlab.kinematics.transforms import homogeneous, rpy_matrix

#: Gravity in the URDF's root frame (the viewer's world: z up).
WORLD_GRAVITY = np.array([0.0, 0.0, -9.81])
#: Limit (rad, either way) a continuous joint gets when its file states none.
CONTINUOUS_LIMIT = np.pi
#: Joint types a chain can move along; "floating"/"planar" joints are read but never driven.
_DRIVABLE = ("revolute", "continuous", "prismatic")


@dataclass
class _UJoint:
    name: str
    kind: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    lower: float
    upper: float
    velocity: float
    effort: float
    limit_default: bool = False
    #: Why this joint cannot be driven as part of a chain (None: it can). Only a
    #: joint on the chosen chain is refused for it; joints off the chain are ignored.
    problem: str | None = None


def _floats(text: str | None, n: int, default: float, where: str) -> np.ndarray:
    if text is None:
        return np.full(n, default)
    try:
        vals = np.array([float(v) for v in text.split()])
    except ValueError:
        raise URDFError(f"{where}: cannot read numbers from {text!r}") from None
    if vals.shape != (n,) or not np.all(np.isfinite(vals)):
        raise URDFError(f"{where}: expected {n} finite numbers, got {text!r}")
    return vals


def _origin(el: ET.Element | None, where: str) -> np.ndarray:
    if el is None:
        return np.eye(4)
    xyz = _floats(el.get("xyz"), 3, 0.0, where + " origin xyz")
    rpy = _floats(el.get("rpy"), 3, 0.0, where + " origin rpy")
    return homogeneous(rpy_matrix(*rpy), xyz)


def _capsule(el: ET.Element, where: str) -> Capsule | None:
    """One ``<collision>`` as a :class:`Capsule` in its link's frame: a sphere as itself; a
    cylinder (its axis the origin's z) as the capsule inside it, its ends rounded within
    its length; a box as the capsule along its longest edge whose radius is half its
    next-longest (covering its widest section). None for a mesh or no geometry: the lab
    takes no contact from a mesh."""
    geometry = el.find("geometry")
    shape = None if geometry is None else next(iter(geometry), None)
    if shape is None or shape.tag not in ("sphere", "cylinder", "box"):
        return None
    T = _origin(el.find("origin"), where)
    R, p = T[:3, :3], T[:3, 3]
    if shape.tag == "sphere":
        r = float(_floats(shape.get("radius"), 1, 0.0, where + " sphere radius")[0])
        half, axis = 0.0, np.array([0.0, 0.0, 1.0])
    elif shape.tag == "cylinder":
        r = float(_floats(shape.get("radius"), 1, 0.0, where + " cylinder radius")[0])
        length = float(_floats(shape.get("length"), 1, 0.0, where + " cylinder length")[0])
        half, axis = max(0.0, length / 2 - r), np.array([0.0, 0.0, 1.0])
    else:
        size = _floats(shape.get("size"), 3, 0.0, where + " box size")
        order = np.argsort(size)[::-1]
        r = float(size[order[1]]) / 2
        half = max(0.0, float(size[order[0]]) / 2 - r)
        axis = np.eye(3)[order[0]]
    if not r >= 0.0:
        raise URDFError(f"{where}: a collision shape's size must not be negative")
    return Capsule(p - half * (R @ axis), p + half * (R @ axis), r)


def _parse_link(el: ET.Element, where: str) -> Link:
    name = el.get("name", "")
    shapes = tuple(c for c in (_capsule(c_el, f"{where} link {name!r} collision")
                               for c_el in el.findall("collision")) if c is not None)
    inertial = el.find("inertial")
    if inertial is None:
        return Link(name, 0.0, np.zeros(3), np.zeros((3, 3)), shapes)
    T = _origin(inertial.find("origin"), f"{where} link {name!r} inertial")
    mass_el = inertial.find("mass")
    mass = float(_floats(mass_el.get("value") if mass_el is not None else None, 1, 0.0,
                         f"{where} link {name!r} mass")[0])
    if mass < 0:
        raise URDFError(f"{where} link {name!r}: negative mass {mass}")
    I = np.zeros((3, 3))
    ie = inertial.find("inertia")
    if ie is not None:
        g = {k: float(_floats(ie.get(k), 1, 0.0, f"{where} link {name!r} {k}")[0])
             for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
        I = np.array([[g["ixx"], g["ixy"], g["ixz"]],
                      [g["ixy"], g["iyy"], g["iyz"]],
                      [g["ixz"], g["iyz"], g["izz"]]])
    R = T[:3, :3]
    return Link(name, mass, T[:3, 3].copy(), R @ I @ R.T, shapes)


def _limit_value(lim: ET.Element, key: str, where: str) -> float | None:
    text = lim.get(key)
    return None if text is None else float(_floats(text, 1, 0.0, f"{where} limit {key}")[0])


def _parse_joint(el: ET.Element, where: str) -> _UJoint:
    """One <joint>. Malformed numbers fail the file; what only stops the joint from
    being driven (its type, a missing <limit>, a zero axis, ``mimic``) is kept in
    ``problem`` and raised only if the joint lies on the chosen chain."""
    name = el.get("name", "")
    kind = el.get("type", "")
    parent, child = el.find("parent"), el.find("child")
    if parent is None or child is None:
        raise URDFError(f"{where}: joint {name!r} needs <parent> and <child>")
    here = f"{where} joint {name!r}"
    axis_el = el.find("axis")
    axis = (_floats(axis_el.get("xyz"), 3, 0.0, here + " axis") if axis_el is not None
            else np.array([1.0, 0.0, 0.0]))
    problem = None
    if kind not in (*_DRIVABLE, "fixed", "floating", "planar"):
        problem = f"has unsupported type {kind!r}"
    elif kind in ("floating", "planar"):
        problem = f"is {kind}: the lab drives revolute joints only"
    elif kind != "fixed":
        norm = np.linalg.norm(axis)
        if norm < 1e-9:
            problem = "has a zero axis"
        else:
            axis = axis / norm
    lim = el.find("limit")
    lower = upper = 0.0
    velocity, effort = np.inf, np.inf
    limit_default = False
    if lim is not None:
        lo, hi = _limit_value(lim, "lower", here), _limit_value(lim, "upper", here)
        v, e = _limit_value(lim, "velocity", here), _limit_value(lim, "effort", here)
        velocity = velocity if v is None else v
        effort = effort if e is None else e
        if kind == "continuous" and (lo is None or hi is None or lo >= hi):
            lo = hi = None  # a continuous joint's <limit> often carries only effort/velocity
        lower = 0.0 if lo is None else lo
        upper = 0.0 if hi is None else hi
        if kind == "continuous" and lo is None:
            lower, upper, limit_default = -CONTINUOUS_LIMIT, CONTINUOUS_LIMIT, True
    elif kind in ("revolute", "prismatic"):
        problem = problem or f"is {kind} and needs a <limit>"
    elif kind == "continuous":
        lower, upper, limit_default = -CONTINUOUS_LIMIT, CONTINUOUS_LIMIT, True
    if lower > upper:
        problem = problem or f"has lower limit {lower} > upper {upper}"
    mimic = el.find("mimic")
    if mimic is not None and kind in _DRIVABLE:
        problem = problem or (f"mimics joint {mimic.get('joint', '?')!r}: it is not driven "
                              "on its own (name a tip_link before it)")
    return _UJoint(name, kind, parent.get("link", ""), child.get("link", ""),
                   _origin(el.find("origin"), here), axis,
                   lower, upper, velocity, effort, limit_default, problem)


def _lump(a: Link, b: Link, T_ab: np.ndarray) -> Link:
    """Inertia of body a plus body b rigidly attached at a <- b = T_ab, in a's frame, and
    the shapes of both."""
    R, p = T_ab[:3, :3], T_ab[:3, 3]
    shapes = a.collision + tuple(Capsule(R @ c.a + p, R @ c.b + p, c.radius)
                                 for c in b.collision)
    if b.mass == 0.0:
        return replace(a, collision=shapes)
    cb = R @ b.com + p
    m = a.mass + b.mass
    com = (a.mass * a.com + b.mass * cb) / m

    def shifted(I: np.ndarray, mass: float, c: np.ndarray) -> np.ndarray:
        d = c - com
        return I + mass * (np.dot(d, d) * np.eye(3) - np.outer(d, d))

    I = shifted(a.inertia, a.mass, a.com) + shifted(R @ b.inertia @ R.T, b.mass, cb)
    return Link(a.name, m, com, I, shapes)


@dataclass
class _Tree:
    path: Path
    links: dict[str, Link]
    joints: dict[str, _UJoint]  # by child link
    children: dict[str, list[_UJoint]]
    root: str


def _read_tree(path: Path) -> _Tree:
    where = str(path)
    try:
        root_el = ET.parse(path).getroot()
    except FileNotFoundError:
        raise URDFError(f"{where}: no such file") from None
    except ET.ParseError as exc:
        raise URDFError(f"{where}: not valid XML ({exc})") from None
    if root_el.tag != "robot":
        raise URDFError(f"{where}: root element is <{root_el.tag}>, expected <robot>")
    links = {}
    for el in root_el.findall("link"):
        link = _parse_link(el, where)
        links[link.name] = link
    joints: dict[str, _UJoint] = {}
    children: dict[str, list[_UJoint]] = {name: [] for name in links}
    for el in root_el.findall("joint"):
        j = _parse_joint(el, where)
        for ln in (j.parent, j.child):
            if ln not in links:
                raise URDFError(f"{where}: joint {j.name!r} names unknown link {ln!r}")
        if j.child in joints:
            raise URDFError(f"{where}: link {j.child!r} has two parent joints")
        joints[j.child] = j
        children[j.parent].append(j)
    roots = [name for name in links if name not in joints]
    if len(roots) != 1:
        raise URDFError(f"{where}: expected one root link, found {roots}")
    return _Tree(path, links, joints, children, roots[0])


def _path_to(tree: _Tree, leaf: str) -> list[_UJoint]:
    """Joints from the tree root down to ``leaf``."""
    path: list[_UJoint] = []
    link = leaf
    while link in tree.joints:
        j = tree.joints[link]
        path.append(j)
        link = j.parent
    path.reverse()
    return path


def _chain_to(tree: _Tree, leaf: str, name: str,
              package_paths: tuple[Path, ...] = ()) -> SerialChain:
    """Build the serial chain from the tree root to ``leaf``.

    Joints off this path are never looked at. On it, fixed joints are folded in; a
    floating or planar joint before the first moving joint (a mobile base) is taken
    at its zero pose; any other joint that cannot be driven raises, naming it.
    """
    path = _path_to(tree, leaf)
    movable = [i for i, j in enumerate(path) if j.kind in _DRIVABLE]
    if not movable:
        raise URDFError(f"{tree.path}: no movable joint between {tree.root!r} and {leaf!r}")
    for i, j in enumerate(path):
        folded_base = i < movable[0] and j.kind in ("fixed", "floating", "planar")
        if j.problem is not None and not folded_base:
            raise URDFError(f"{tree.path}: joint {j.name!r} on the chain to {leaf!r} "
                            f"{j.problem}")
    base_pose = np.eye(4)
    for j in path[: movable[0]]:
        base_pose = base_pose @ j.origin
    joints: list[Joint] = []
    links: list[Link] = []
    names: list[str] = []
    pending = np.eye(4)  # fixed transforms waiting to be folded into the next joint
    for j in path[movable[0]:]:
        if j.kind == "fixed":
            # Body on a fixed joint rides on the last moving link.
            pending = pending @ j.origin
            links[-1] = _lump(links[-1], tree.links[j.child], pending)
            continue
        joints.append(Joint(j.name, j.kind, pending @ j.origin if joints else j.origin,
                            j.axis, j.lower, j.upper, j.velocity, j.effort, j.limit_default))
        links.append(tree.links[j.child])
        names.append(j.child)
        pending = np.eye(4)
    R = base_pose[:3, :3]
    return SerialChain(name=name, joints=tuple(joints), links=tuple(links),
                       base_pose=base_pose, tip=pending, gravity=R.T @ WORLD_GRAVITY,
                       urdf_path=tree.path, link_names=tuple(names),
                       package_paths=tuple(Path(p) for p in package_paths))


def _leaves(tree: _Tree) -> list[str]:
    return [name for name, kids in tree.children.items() if not kids and name != tree.root]


def _default_tip(tree: _Tree) -> str:
    """The only leaf, or else the leaf below the most revolute joints among those
    reached through revolute, continuous and fixed joints only (a camera or base link
    has none; a gripper finger's path has a prismatic or mimic joint). Two leaves
    tying need ``tip_link``."""
    leaves = _leaves(tree)
    if len(leaves) == 1:
        return leaves[0]
    depth: dict[str, int] = {}
    for leaf in leaves:
        path = _path_to(tree, leaf)
        first = next((i for i, j in enumerate(path) if j.kind in _DRIVABLE), len(path))
        arm = path[first:]
        if all(j.kind == "fixed" or (j.kind in ("revolute", "continuous") and j.problem is None)
               for j in arm):
            depth[leaf] = sum(j.kind != "fixed" for j in arm)
    best = max(depth.values(), default=0)
    tips = [leaf for leaf, d in depth.items() if d == best]
    if len(tips) != 1 or best == 0:
        raise URDFError(f"{tree.path}: not a serial chain (leaf links {leaves}); "
                        "name the end effector with tip_link (--tip-link LINK)")
    return tips[0]


def chain_from_urdf(path: str | Path, *, tip_link: str | None = None,
                    package_paths: tuple[str | Path, ...] = ()) -> SerialChain:
    """Parse a URDF file into a :class:`SerialChain` from its root to ``tip_link``.

    Without ``tip_link`` the chain ends at the file's only leaf link, or else at the
    leaf below the most revolute joints whose path has no prismatic, mimic or
    floating joint (an error naming the leaves when two tie).
    Joints off the chain are ignored whatever their type.

    Args:
        path: the .urdf file.
        tip_link: the end-effector link.
        package_paths: folders to look in for ``package://NAME/...`` meshes (the
            viewer's; the URDF's own folder and its parents are always tried).

    Raises:
        URDFError: naming the file and the reason when it is malformed, or naming the
            joint on the chain that cannot be driven.
    """
    tree = _read_tree(Path(path))
    if tip_link is None:
        tip_link = _default_tip(tree)
    elif tip_link not in tree.links:
        raise URDFError(f"{path}: no link named {tip_link!r}; links: {', '.join(tree.links)}")
    name = ET.parse(path).getroot().get("name", Path(path).stem)
    return _chain_to(tree, tip_link, name, tuple(Path(p) for p in package_paths))


def _named_joint(path: str | Path, joint: str) -> _UJoint:
    """The URDF joint named ``joint``, wherever it is in the tree; URDFError naming the
    file, the joint and the joints it has otherwise."""
    tree = _read_tree(Path(path))
    found = next((j for j in tree.joints.values() if j.name == joint), None)
    if found is None:
        names = ", ".join(j.name for j in tree.joints.values())
        raise URDFError(f"{path}: no joint named {joint!r}; joints: {names}")
    return found


def joint_limits(path: str | Path, joint: str) -> tuple[float, float]:
    """(lower, upper) of the URDF joint named ``joint``, wherever it is in the tree (rad,
    or m for a prismatic joint: a gripper's finger, off the arm's chain).

    Raises:
        URDFError: naming the file and the joint when it has no such joint, or a joint
            without limits.
    """
    found = _named_joint(path, joint)
    if found.kind not in _DRIVABLE or found.lower >= found.upper:
        raise URDFError(f"{path}: joint {joint!r} ({found.kind}) has no limits to drive "
                        "between")
    return found.lower, found.upper


def joint_kind(path: str | Path, joint: str) -> str:
    """The type of the URDF joint named ``joint`` ("revolute", "prismatic", ...), wherever
    it is in the tree: whether a gripper's finger turns (rad) or slides (m).

    Raises:
        URDFError: naming the file and the joint when it has no such joint.
    """
    return _named_joint(path, joint).kind


LEG_NAMES = ("RF", "LF", "RH", "LH")


def holds_quadruped(path: str | Path) -> bool:
    """Whether URDF ``path`` has a foot link for every leg of :data:`LEG_NAMES`
    (``<LEG>_foot``): a quadruped, read by :func:`quadruped_from_urdf`."""
    tree = _read_tree(Path(path))
    return all(f"{leg}_foot" in tree.links for leg in LEG_NAMES)


def quadruped_from_urdf(path: str | Path) -> Quadruped:
    """Parse a quadruped URDF whose feet are links named ``<LEG>_foot`` (LEG in LEG_NAMES)."""
    tree = _read_tree(Path(path))
    legs = {}
    for leg in LEG_NAMES:
        foot = f"{leg}_foot"
        if foot not in tree.links:
            raise URDFError(f"{path}: quadruped needs a link named {foot!r}")
        chain = _chain_to(tree, foot, leg)
        if chain.n != 3:
            raise URDFError(f"{path}: leg {leg} has {chain.n} joints, expected 3")
        legs[leg] = chain
    body = tree.root
    name = ET.parse(path).getroot().get("name", Path(path).stem)
    return Quadruped(name, legs, tree.links[body].mass, Path(path), body)
