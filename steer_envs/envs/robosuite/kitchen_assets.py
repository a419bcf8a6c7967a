"""The Kitchen scene's MJCF assets: a microwave converted from gymnasium-robotics, and our own bowl.

robosuite ships no microwave. gymnasium-robotics (a dependency) ships
FrankaKitchen's, with a hinged door (``microwave_{asset,chain}.xml``), but
robosuite's ``MujocoXMLObject`` cannot load it as is: robosuite reads no
nested default classes and ignores ``childclass``. :func:`asset_dir` converts
it at build time into robosuite's object layout: every default attribute is
inlined on its geom or joint (no classes left), collision geoms move from
group 4 to group 0 (robosuite keeps groups 0 and 1) and are made invisible
(the meshes are the look), asset paths become absolute, the door's joint
friction is lowered (a Panda pulls the handle without slipping), the
handle's top bracket is dropped (the bar stands on its bottom bracket, so
fingers pointing down can close around the bar's top) and
robosuite's ``bottom_site`` / ``top_site`` / ``horizontal_radius_site`` are
added. The bowl is a small MJCF of our own (a disc and a ring of wall boxes).

Both files are written into a cache folder named by a hash of the sources
and this converter's settings (``$XDG_CACHE_HOME/steer-envs/kitchen-assets``,
``~/.cache`` when unset), atomically (:func:`steer_envs.io.atomic_directory`),
so concurrent builds and killed ones never leave a torn file. Nothing is
downloaded. Nothing here imports robosuite.
"""

from __future__ import annotations

import hashlib
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from steer_envs.io import atomic_directory, default_cache_dir

__all__ = [
    "BOWL_FILE",
    "BOWL_HEIGHT",
    "BOWL_RADIUS",
    "DOOR_DAMPING",
    "DOOR_FRICTIONLOSS",
    "DOOR_JOINT",
    "MICROWAVE_FILE",
    "asset_dir",
    "bowl_xml",
    "cache_root",
    "microwave_source",
    "microwave_xml",
]

#: the bowl's outer radius (m): the open Panda fingers (8 cm) close around it.
BOWL_RADIUS = 0.03
#: the bowl's height (m), base included.
BOWL_HEIGHT = 0.04
_BOWL_WALL = 0.006  # m: wall thickness
_BOWL_BASE = 0.006  # m: base disc thickness
_BOWL_SEGMENTS = 10
#: the door hinge's name in the source file (robosuite prefixes it with the object's name).
DOOR_JOINT = "microwave"
#: the hinge's joint friction (N m, source: 2) and damping (N m s / rad, source: 2).
DOOR_FRICTIONLOSS = 0.4
DOOR_DAMPING = 0.5
MICROWAVE_FILE = "microwave.xml"
BOWL_FILE = "bowl.xml"
_VERSION = "2"  # bump when the conversion changes: a new cache folder is built

# the source's default classes, flattened (class -> attributes inlined on each element)
_VISUAL = {"conaffinity": "0", "contype": "0", "group": "1", "material": "micro_black", "type": "mesh"}
_COLLISION = {
    "conaffinity": "1",
    "condim": "3",
    "contype": "0",
    "group": "0",
    "margin": "0.001",
    "solimp": ".8 .9 .01",
    "solref": ".02 1",
    "rgba": "0 0 0 0",
}
_JOINT = {"damping": str(DOOR_DAMPING), "frictionloss": str(DOOR_FRICTIONLOSS), "armature": ".01", "limited": "true"}


def microwave_source() -> Path:
    """The folder of gymnasium-robotics' FrankaKitchen item assets (``microwave_*.xml``)."""
    import importlib.util

    spec = importlib.util.find_spec("gymnasium_robotics")
    if spec is None or spec.origin is None:
        raise ImportError("the Kitchen env needs gymnasium-robotics (its FrankaKitchen microwave)")
    return Path(spec.origin).parent / "envs" / "assets" / "kitchen_franka" / "kitchen_assets" / "item_assets"


def cache_root() -> Path:
    """``$XDG_CACHE_HOME/steer-envs/kitchen-assets`` (``~/.cache`` when unset), by ``default_cache_dir``."""
    return default_cache_dir("kitchen-assets")


def microwave_xml(source: Path) -> str:
    """The converted microwave MJCF text (robosuite's object layout) from the source folder."""
    asset_src = ET.parse(source / "microwave_asset.xml").getroot()
    chain = ET.parse(source / "microwave_chain.xml").getroot()
    root = ET.Element("mujoco", model="microwave")
    asset = ET.SubElement(root, "asset")
    for el in asset_src.find("asset") or []:
        el = _copy(el)
        if el.tag == "mesh":
            el.set("file", str((source / el.get("file", "")).resolve()))
        elif el.tag == "texture":
            el.set("file", str((source.parent / "textures" / el.get("file", "")).resolve()))
        asset.append(el)
    world = ET.SubElement(root, "worldbody")
    outer = ET.SubElement(world, "body")
    obj = ET.SubElement(outer, "body", name="object")
    micro = chain.find("body")
    if micro is None:
        raise ValueError(f"{source / 'microwave_chain.xml'}: no body")
    _convert_children(micro, obj)
    # robosuite's sites: the bottom (z = 0), top and horizontal radius of the body (source units)
    for name, pos in (
        ("bottom_site", "0 0 0"),
        ("top_site", "0 0 0.374"),
        ("horizontal_radius_site", "0.345 0.221 0"),
    ):
        ET.SubElement(outer, "site", name=name, pos=pos, size="0.005", rgba="0 0 0 0")
    ET.indent(root)
    return ET.tostring(root, encoding="unicode")


def _copy(el: ET.Element) -> ET.Element:
    out = ET.Element(el.tag, dict(el.attrib))
    for child in el:
        out.append(_copy(child))
    return out


def _convert_children(src: ET.Element, dst: ET.Element) -> None:
    """Copy ``src``'s children into ``dst`` with the default classes inlined (recursively for bodies)."""
    for el in src:
        attrib = {k: v for k, v in el.attrib.items() if k not in ("class", "childclass")}
        if el.tag == "geom" and _is_top_bracket(attrib):
            continue
        if el.tag == "geom":
            base = _COLLISION if el.get("class") == "micro_collision" else _VISUAL
            merged = {**base, **attrib}
            if merged["group"] == "4":
                merged["group"] = "0"
            if base is _COLLISION:
                merged["group"], merged["rgba"] = "0", "0 0 0 0"
                merged.pop("material", None)
            elif "size" in attrib and "mesh" not in attrib:
                merged["type"] = attrib.get("type", "box")
            ET.SubElement(dst, "geom", merged)
        elif el.tag == "joint":
            ET.SubElement(dst, "joint", {**_JOINT, **attrib})
        elif el.tag == "site":
            ET.SubElement(dst, "site", attrib)
        elif el.tag == "body":
            body = ET.SubElement(dst, "body", attrib)
            _convert_children(el, body)


def _is_top_bracket(attrib: dict[str, str]) -> bool:
    """The handle's top bracket: a capsule across the door, above the bar's centre (``pos`` z > 0.1)."""
    if attrib.get("type") != "capsule" or "euler" not in attrib:
        return False
    return float(attrib.get("pos", "0 0 0").split()[2]) > 0.1


def bowl_xml() -> str:
    """The bowl's MJCF text: a base disc and a ring of wall boxes (robosuite's object layout, body ``object``)."""
    root = ET.Element("mujoco", model="bowl")
    asset = ET.SubElement(root, "asset")
    ET.SubElement(asset, "material", name="bowl_mat", rgba="0.95 0.95 0.9 1", specular="0.3", shininess="0.3")
    world = ET.SubElement(root, "worldbody")
    outer = ET.SubElement(world, "body")
    obj = ET.SubElement(outer, "body", name="object")
    half_h = BOWL_HEIGHT / 2
    common = {"friction": "1.5 0.01 0.001", "density": "400", "solref": "0.01 1", "material": "bowl_mat"}
    base = {
        "name": "base",
        "type": "cylinder",
        "pos": f"0 0 {-half_h + _BOWL_BASE / 2}",
        "size": f"{BOWL_RADIUS - _BOWL_WALL / 2} {_BOWL_BASE / 2}",
        "group": "0",
    }
    ET.SubElement(obj, "geom", {**base, **common})
    r = BOWL_RADIUS - _BOWL_WALL / 2
    half_w = r * np.tan(np.pi / _BOWL_SEGMENTS) + 0.0005
    for k in range(_BOWL_SEGMENTS):
        a = 2 * np.pi * k / _BOWL_SEGMENTS
        wall = {
            "name": f"wall{k}",
            "type": "box",
            "pos": f"{r * np.cos(a):.6f} {r * np.sin(a):.6f} 0",
            "euler": f"0 0 {a:.6f}",
            "size": f"{_BOWL_WALL / 2} {half_w:.6f} {half_h}",
            "group": "0",
        }
        ET.SubElement(obj, "geom", {**wall, **common})
    for name, pos in (
        ("bottom_site", f"0 0 {-half_h}"),
        ("top_site", f"0 0 {half_h}"),
        ("horizontal_radius_site", f"{BOWL_RADIUS} 0 0"),
    ):
        ET.SubElement(outer, "site", name=name, pos=pos, size="0.002", rgba="0 0 0 0")
    ET.indent(root)
    return ET.tostring(root, encoding="unicode")


def asset_dir(root: Path | None = None) -> Path:
    """The cache folder holding :data:`MICROWAVE_FILE` and :data:`BOWL_FILE`, built on first use (atomically).

    ``root``: the cache root (default :func:`cache_root`). The folder's name
    hashes the source files and the converter, so a changed source or
    converter builds a new one.
    """
    source = microwave_source()
    texts = {MICROWAVE_FILE: microwave_xml(source), BOWL_FILE: bowl_xml()}
    digest = hashlib.sha256(_VERSION.encode())
    for name in sorted(texts):
        digest.update(name.encode() + b"\0" + texts[name].encode())
    folder = (cache_root() if root is None else Path(root)) / f"v{_VERSION}-{digest.hexdigest()[:16]}"
    if all((folder / name).is_file() for name in texts):
        return folder
    try:
        with atomic_directory(folder) as tmp:
            for name, text in texts.items():
                (tmp / name).write_text(text)
    except FileExistsError:  # another process built it first
        if not all((folder / name).is_file() for name in texts):
            raise
    return folder
