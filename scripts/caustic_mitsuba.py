#!/usr/bin/env python3
"""Bitterli's volumetric-caustic (pbrt-v4 file) translated to Mitsuba 3 and rendered by it, to
check our `path` through its medium against another renderer on the same file.

    pip install mitsuba numpy
    python3 scripts/volumetric_caustic_mitsuba.py COLLECTION/volumetric-caustic/pbrt/scene-v4.pbrt OUT \
        [--resolution 64] [--spp 1024] [--seeds 4] [--light-size S]

writes OUT/scene.xml (and the meshes as OBJ files beside it), renders it --seeds times at
--spp samples per pixel (scalar_rgb, volpath, the file's maxdepth 7 as Mitsuba's max_depth 8)
and prints the image mean per channel. The walls are pbrt's two-sided diffuse (Mitsuba's
`twosided`), the front wall the `null` boundary of the gas, the sphere glass of index 1.5 in
the gas. --light-size S replaces the tiny light by an S x S square of the same power, at the
same place (the caustic's fireflies then stop hiding a difference): render the written
OUT/scene.pbrt with zvidpt to compare.

Compare with `zvidpt render FILE --integrator path --resolution RxR --spp N --seed 11` and
`zvidpt info` (both are heavy-tailed at the file's own light: compare several seeds).
"""
import argparse
import re
import time
from pathlib import Path

import numpy as np


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
    src = Path(a.pbrt).read_text()
    light = [float(x) for x in re.search(r'"rgb L" \[([^\]]*)\]', src).group(1).split()]
    if a.light_size:
        # The file's light: 0.005 x 0.004 at y = 1.98, centred on (-0.005, -0.03).
        old = re.search(r'"point3 P" \[ (-0\.0025 1\.98[^\]]*)\]', src).group(1)
        area = 0.005 * 0.004
        h = a.light_size / 2
        cx, cz = -0.005, -0.03
        new = f"{cx + h} 1.98 {cz + h} {cx - h} 1.98 {cz + h} {cx - h} 1.98 {cz - h} {cx + h} 1.98 {cz - h} "
        src = src.replace(old, new)
        light = [v * area / a.light_size ** 2 for v in light]
        src = re.sub(r'"rgb L" \[[^\]]*\]', '"rgb L" [ ' + " ".join(map(str, light)) + " ]", src)
        (out / "scene.pbrt").write_text(src)
    m = re.search(r"^Transform \[([^\]]*)\]", src, re.M)
    camera_from_world = np.array([float(x) for x in m.group(1).split()]).reshape(4, 4).T
    world = np.linalg.inv(camera_from_world)
    eye, fwd, up = world @ [0, 0, 0, 1], world @ [0, 0, 1, 0], world @ [0, 1, 0, 0]
    fov = float(re.search(r'"float fov" \[ *([0-9.]+)', src).group(1))
    meshes, material = [], None
    for block in re.split(r"\n(?=\s*(?:NamedMaterial|Shape|AttributeEnd|AreaLightSource|MediumInterface))", src):
        b = block.strip()
        if b.startswith("NamedMaterial"):
            material = re.match(r'NamedMaterial "(\w+)"', b).group(1)
        elif b.startswith('Shape "trianglemesh"'):
            p = [float(x) for x in re.search(r'"point3 P" \[([^\]]*)\]', b).group(1).split()]
            i = [int(x) for x in re.search(r'"integer indices" \[([^\]]*)\]', b).group(1).split()]
            meshes.append((material, p, i))
    colours = {"LeftWall": "0.63 0.065 0.05", "RightWall": "0.14 0.45 0.091"}
    v = lambda x: ", ".join(str(c) for c in x[:3])
    xml = [f"""<scene version="3.0.0">
<integrator type="volpath"><integer name="max_depth" value="8"/></integrator>
<medium type="homogeneous" id="gas"><rgb name="albedo" value="1, 1, 1"/><float name="sigma_t" value="1"/></medium>
<sensor type="perspective"><float name="fov" value="{fov}"/><string name="fov_axis" value="smaller"/>
<transform name="to_world"><lookat origin="{v(eye)}" target="{v(eye + fwd)}" up="{v(up)}"/></transform>
<film type="hdrfilm"><integer name="width" value="{a.resolution}"/><integer name="height" value="{a.resolution}"/>
<rfilter type="box"/></film></sensor>
<shape type="sphere"><point name="center" x="-0.22827" y="1.2" z="0.152505"/><float name="radius" value="0.3"/>
<bsdf type="dielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf>
<ref name="exterior" id="gas"/></shape>"""]
    for k, (mat, p, i) in enumerate(meshes):
        with open(out / f"mesh{k}.obj", "w") as f:
            f.writelines(f"v {p[j]} {p[j + 1]} {p[j + 2]}\n" for j in range(0, len(p), 3))
            f.writelines(f"f {i[j] + 1} {i[j + 1] + 1} {i[j + 2] + 1}\n" for j in range(0, len(i), 3))
        shape = f'<shape type="obj"><string name="filename" value="mesh{k}.obj"/><boolean name="face_normals" value="true"/>'
        if mat == "FrontWall":
            xml.append(shape + '<bsdf type="null"/><ref name="interior" id="gas"/></shape>')
        elif mat == "Light":
            xml.append(shape + '<bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>'
                       f'<emitter type="area"><rgb name="radiance" value="{v(light)}"/></emitter>'
                       '<ref name="exterior" id="gas"/></shape>')
        else:
            rho = colours.get(mat, "0.725 0.71 0.68")
            xml.append(shape + f'<bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="{rho}"/>'
                       "</bsdf></bsdf></shape>")
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
