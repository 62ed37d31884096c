#!/usr/bin/env python3
"""Bitterli's two caustic Cornell boxes (pbrt-v4 files: volumetric-caustic, water-caustic)
translated to Mitsuba 3 and rendered by it, to check our `path` against another renderer on
the same file.

    pip install mitsuba numpy
    python3 scripts/caustic_mitsuba.py COLLECTION/SCENE/pbrt/scene-v4.pbrt OUT \
        [--resolution 64] [--spp 1024] [--seeds 4] [--light-size S]

writes OUT/scene.xml (the triangle meshes as OBJ files beside it; PLY meshes are read where
they are), renders it --seeds times at --spp samples per pixel (scalar_rgb; `volpath` with
the file's medium, `path` without; the file's maxdepth N as Mitsuba's max_depth N + 1, which
counts the emitter's vertex) and prints the image mean per channel. The subset these two
files use: named `diffuse` (pbrt's are two-sided: Mitsuba's `twosided`), `dielectric` (`eta`)
and `interface` (`null`) materials; `trianglemesh`, `plymesh` and `sphere` shapes under a
`Transform`; one homogeneous medium named by `MediumInterface`; one `diffuse` area light.
Anything else stops the script. --light-size S replaces the tiny light by an S x S square of
the same power centred where it was (the caustic's fireflies then stop hiding a difference),
and writes that file as OUT/scene.pbrt (beside the original's folder's meshes, by absolute
path) for zvidpt to render.

Compare with `zvidpt render FILE --integrator path --resolution RxR --spp N --seed 11` (both are
heavy-tailed at the file's own light: compare several seeds).
"""
import argparse
import re
import time
from pathlib import Path

import numpy as np


def floats(block, name):
    m = re.search(rf'"(?:float|rgb|point3|integer) {name}" \[([^\]]*)\]', block)
    return [float(x) for x in m.group(1).split()] if m else None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("pbrt")
    ap.add_argument("out")
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--light-size", type=float, default=None)
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    folder = Path(a.pbrt).resolve().parent
    src = Path(a.pbrt).read_text()
    light_block = re.search(r'AreaLightSource "diffuse"(.*?)AttributeEnd', src, re.S).group(1)
    light = floats(light_block, "L")
    if a.light_size:
        p = np.array(floats(light_block, "P")).reshape(-1, 3)
        area = (p[:, 0].max() - p[:, 0].min()) * (p[:, 2].max() - p[:, 2].min())
        (cx, y, cz), h = p.mean(0), a.light_size / 2
        new_p = f"{cx + h} {y} {cz + h} {cx - h} {y} {cz + h} {cx - h} {y} {cz - h} {cx + h} {y} {cz - h}"
        new_light = [v * area / a.light_size**2 for v in light]
        new_block = re.sub(r'"point3 P" \[[^\]]*\]', f'"point3 P" [ {new_p} ]', light_block)
        new_block = re.sub(r'"rgb L" \[[^\]]*\]', '"rgb L" [ ' + " ".join(map(str, new_light)) + " ]", new_block)
        src = src.replace(light_block, new_block)
        light = new_light
        # Mesh files by absolute path, so that OUT/scene.pbrt renders from anywhere.
        src = re.sub(r'"string filename" \[ "(models/[^"]*)" \]', lambda m: f'"string filename" [ "{folder / m.group(1)}" ]',
                     src)
        (out / "scene.pbrt").write_text(src)
    depth = int(floats(src, "maxdepth")[0])
    m = re.search(r"^Transform \[([^\]]*)\]", src, re.M)
    world = np.linalg.inv(np.array([float(x) for x in m.group(1).split()]).reshape(4, 4).T)
    eye, fwd, up = world @ [0, 0, 0, 1], world @ [0, 0, 1, 0], world @ [0, 1, 0, 0]
    fov = floats(src, "fov")[0]
    materials = {}
    for name, body in re.findall(r'MakeNamedMaterial "(\w+)"((?:\s+"[^"]+" \[[^\]]*\])*)', src):
        kind = re.search(r'"string type" \[ "(\w+)" \]', body).group(1)
        if kind == "diffuse":
            materials[name] = ("diffuse", floats(body, "reflectance"))
        elif kind == "dielectric":
            materials[name] = ("dielectric", floats(body, "eta")[0])
        elif kind == "interface":
            materials[name] = ("interface", None)
        else:
            raise SystemExit(f"material {name}: type {kind} is outside this script's subset")
    medium = re.search(r'MakeNamedMedium "(\w+)"((?:\s+"[^"]+" \[[^\]]*\])*)', src)
    v = lambda x: ", ".join(str(c) for c in x[:3])  # noqa: E731
    xml = [f'<scene version="3.0.0">\n<integrator type="{"volpath" if medium else "path"}">'
           f'<integer name="max_depth" value="{depth + 1}"/></integrator>']
    if medium:
        body = medium.group(2)
        if re.search(r'"string type" \[ "(\w+)" \]', body).group(1) != "homogeneous":
            raise SystemExit("only a homogeneous medium is in this script's subset")
        scale = (floats(body, "scale") or [1.0])[0]
        sa, ss = np.array(floats(body, "sigma_a")) * scale, np.array(floats(body, "sigma_s")) * scale
        st = sa + ss
        albedo = np.where(st > 0, ss / np.maximum(st, 1e-30), 0)
        xml.append(f'<medium type="homogeneous" id="{medium.group(1)}"><rgb name="albedo" value="{v(albedo)}"/>'
                   f'<rgb name="sigma_t" value="{v(st)}"/></medium>')
    xml.append(f"""<sensor type="perspective"><float name="fov" value="{fov}"/><string name="fov_axis" value="smaller"/>
<transform name="to_world"><lookat origin="{v(eye)}" target="{v(eye + fwd)}" up="{v(up)}"/></transform>
<film type="hdrfilm"><integer name="width" value="{a.resolution}"/><integer name="height" value="{a.resolution}"/>
<rfilter type="box"/></film></sensor>""")
    # The shapes in order, with the state pbrt's attribute stack gives each.
    state = {"material": None, "transform": np.eye(4), "interface": ("", ""), "light": False}
    stack, k = [], 0
    statements = re.split(r'\n\s*(?=(?:AttributeBegin|AttributeEnd|NamedMaterial|Transform|Shape|MediumInterface|'
                          r'AreaLightSource)\b)', src.split("WorldBegin", 1)[1])
    for st in statements:
        st = st.strip()
        if st.startswith("AttributeBegin"):
            stack.append(dict(state))
        elif st.startswith("AttributeEnd"):
            state = stack.pop()
        elif st.startswith("NamedMaterial"):
            state["material"] = re.match(r'NamedMaterial "(\w+)"', st).group(1)
        elif st.startswith("Transform"):
            state["transform"] = np.array([float(x) for x in re.search(r"\[([^\]]*)\]", st).group(1).split()]
                                          ).reshape(4, 4).T
        elif st.startswith("MediumInterface"):
            state["interface"] = tuple(re.findall(r'"(\w*)"', st)[:2])
        elif st.startswith("AreaLightSource"):
            state["light"] = True
        elif st.startswith("Shape"):
            kind = re.match(r'Shape "(\w+)"', st).group(1)
            matrix = " ".join(f"{x:.9g}" for x in state["transform"].reshape(-1))
            to_world = f'<transform name="to_world"><matrix value="{matrix}"/></transform>'
            if kind == "trianglemesh":
                p, i = floats(st, "P"), [int(x) for x in floats(st, "indices")]
                with open(out / f"mesh{k}.obj", "w") as f:
                    f.writelines(f"v {p[j]} {p[j + 1]} {p[j + 2]}\n" for j in range(0, len(p), 3))
                    f.writelines(f"f {i[j] + 1} {i[j + 1] + 1} {i[j + 2] + 1}\n" for j in range(0, len(i), 3))
                shape = (f'<shape type="obj"><string name="filename" value="mesh{k}.obj"/>{to_world}'
                         '<boolean name="face_normals" value="true"/>')
                k += 1
            elif kind == "plymesh":
                name = re.search(r'"string filename" \[ "([^"]*)" \]', st).group(1)
                shape = (f'<shape type="ply"><string name="filename" value="{folder / name}"/>{to_world}'
                         '<boolean name="face_normals" value="true"/>')
            elif kind == "sphere":
                shape = f'<shape type="sphere"><float name="radius" value="{floats(st, "radius")[0]}"/>{to_world}'
            else:
                raise SystemExit(f"shape {kind} is outside this script's subset")
            inside, outside = state["interface"]
            media = "".join(f'<ref name="{side}" id="{m}"/>' for side, m in (("interior", inside), ("exterior", outside))
                            if m)
            kind, value = materials[state["material"]]
            if state["light"]:
                xml.append(shape + '<bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>'
                           f'<emitter type="area"><rgb name="radiance" value="{v(light)}"/></emitter>{media}</shape>')
            elif kind == "interface":
                xml.append(shape + f'<bsdf type="null"/>{media}</shape>')
            elif kind == "dielectric":
                xml.append(shape + f'<bsdf type="dielectric"><float name="int_ior" value="{value}"/>'
                           f'<float name="ext_ior" value="1"/></bsdf>{media}</shape>')
            else:
                xml.append(shape + f'<bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" '
                           f'value="{v(value)}"/></bsdf></bsdf>{media}</shape>')
    xml.append("</scene>")
    (out / "scene.xml").write_text("\n".join(xml))
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    scene = mi.load_file(str(out / "scene.xml"))
    start = time.time()
    images = np.stack([np.array(mi.render(scene, spp=a.spp, seed=s))[:, :, :3] for s in range(a.seeds)])
    means = images.mean((1, 2))
    print(f"Mitsuba 3, {a.resolution}x{a.resolution}, {a.seeds} x {a.spp} spp, {time.time() - start:.0f} s: "
          f"mean RGB {means.mean(0).round(5).tolist()} (per seed: {means.round(4).tolist()})")


if __name__ == "__main__":
    main()
