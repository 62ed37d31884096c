"""The subset of zvidpt's TOML scenes that a peer renderer is given exactly: a pinhole camera
(`eye`, `look_at`, `up`, vertical `fov_y`), the one-pixel box filter, OBJ meshes
(`reverse_winding` allowed) with two-sided Lambertian materials (MTL `Kd`, or a `[materials]`
entry's `diffuse`) and one-sided emitters (`emission`, front along the geometric normal as
wound). Anything else is refused rather than approximated. Used by `race.py` (Mitsuba 3) and
`race_cycles.py` (Cycles)."""
import sys
import tomllib

MESH_KEYS = {"obj", "material", "reverse_winding"}
MATERIAL_KEYS = {"diffuse", "emission"}
CAMERA_KEYS = {"eye", "look_at", "up", "fov_y", "width", "height"}


def refuse(peer, message):
    sys.exit(f"peers: {message}: not in the subset {peer} is given exactly")


def read_scene(folder, peer):
    """The TOML scene's camera, meshes and materials, checked against the subset."""
    d = tomllib.loads((folder / "scene.toml").read_text())
    for key in d:
        if key not in {"camera", "materials", "mesh"}:
            refuse(peer, f"[{key}]")
    cam = d["camera"]
    if set(cam) - CAMERA_KEYS:
        refuse(peer, f"camera keys {sorted(set(cam) - CAMERA_KEYS)}")
    materials = d.get("materials", {})
    for name, m in materials.items():
        if set(m) - MATERIAL_KEYS:
            refuse(peer, f"material {name} keys {sorted(set(m) - MATERIAL_KEYS)}")
        if max(m.get("emission", [0.0])) > 0 and max(m.get("diffuse", [0.0])) > 0:
            refuse(peer, f"material {name}: an emitter that also reflects")
    meshes = d.get("mesh", [])
    for m in meshes:
        if set(m) - MESH_KEYS:
            refuse(peer, f"mesh keys {sorted(set(m) - MESH_KEYS)}")
        if "material" in m and m["material"] not in materials:
            refuse(peer, f"material {m['material']} not defined")
    return cam, materials, meshes


def mtl_colours(obj_path, peer):
    """`Kd` of each material of the OBJ's MTL files."""
    colours = {}
    for line in obj_path.read_text().splitlines():
        if line.startswith("mtllib "):
            name = None
            for l in (obj_path.parent / line.split(None, 1)[1].strip()).read_text().splitlines():
                t = l.split()
                if t and t[0] == "newmtl":
                    name = t[1]
                elif t and t[0] == "Kd" and name:
                    colours[name] = [float(x) for x in t[1:4]]
                elif t and t[0] not in ("newmtl", "Kd") and not t[0].startswith("#"):
                    refuse(peer, f"MTL statement {t[0]}")
    return colours


def surface(materials, kd, mesh, name, peer):
    """(reflectance, radiance) of a mesh's faces of OBJ material `name`: the `[materials]` entry
    the mesh names if it names one, else the MTL's `Kd` of `name` (not an emitter)."""
    if "material" in mesh:
        m = materials[mesh["material"]]
        return m.get("diffuse", [0.5] * 3), m.get("emission", [0.0] * 3)
    if name not in kd:
        refuse(peer, f"material {name} has no Kd")
    return kd[name], [0.0] * 3


def obj_groups(obj_path, reverse_winding, peer):
    """The OBJ's triangles grouped by `usemtl` name: {name: [(p0, p1, p2), ...]} (positions only,
    polygons fanned from their first vertex, the winding reversed if asked)."""
    positions, groups, current = [], {}, None
    for line in obj_path.read_text().splitlines():
        t = line.split()
        if not t or t[0].startswith("#") or t[0] in ("o", "g", "s", "mtllib", "vn", "vt"):
            continue
        if t[0] == "v":
            positions.append(tuple(float(x) for x in t[1:4]))
        elif t[0] == "usemtl":
            current = t[1]
        elif t[0] == "f":
            idx = [int(v.split("/")[0]) for v in t[1:]]
            idx = [i - 1 if i > 0 else len(positions) + i for i in idx]
            for k in range(1, len(idx) - 1):
                tri = (positions[idx[0]], positions[idx[k]], positions[idx[k + 1]])
                if reverse_winding:
                    tri = (tri[0], tri[2], tri[1])
                groups.setdefault(current, []).append(tri)
        else:
            refuse(peer, f"{obj_path.name}: OBJ statement {t[0]}")
    return groups
