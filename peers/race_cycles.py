"""zvidpt against Blender's Cycles (path tracing, and path guiding with Open PGL) at equal time.

    pip install bpy numpy OpenEXR        # bpy: Blender 5.0 for CPython 3.11
    python3 peers/race_cycles.py SCENE_DIR OUT [--time 20] [--seeds 1,2] [--threads 2] [--ref-spp 8192]
        [--integrators "path;zvidpt"] [--resolution WxH] [--mitsuba] [--zvidpt BIN]

SCENE_DIR is a zvidpt TOML scene of the subset Cycles can be given exactly (`scenes/cornell-paper`,
`cornell-blocks`, `cornell-classic`, `partition`): a pinhole camera (`eye`, `look_at`, `up`,
vertical `fov_y`), the one-pixel box filter, OBJ meshes (`reverse_winding` allowed) with
two-sided Lambertian materials (MTL `Kd`, or a `[materials]` entry's `diffuse`) and one-sided
emitters (`emission`). Anything else is refused rather than approximated. The
translation into Cycles:

- each OBJ imported without axis conversion (zvidpt's coordinates as they are), each material a
  Diffuse BSDF of its reflectance; an emitter's front (its geometric normal, as wound) an
  Emission of its radiance, its back black (`Backfacing` mask), and Cycles told to sample only
  its front (`emission_sampling = FRONT`): a Cycles mesh light otherwise emits from both sides;
- the camera at `eye` looking along `look_at - eye`, `up` up, vertical field of view `fov_y`;
- a box pixel filter one pixel wide, no clamping, no glossy filter, no denoising, no adaptive
  sampling, 1024 bounces of every kind (Cycles' Russian roulette ends paths), a black world,
  the `Standard` view transform (the EXR holds linear Rec.709 radiance, as zvidpt's);
- Cycles' own sampling pattern (`sampling_pattern`, printed) and its `seed`;
- equal time through Cycles' `time_limit` (rendering after scene synchronisation; the wall
  seconds of the whole render call are what is reported), `--threads` CPU threads;
- guiding: `use_guiding`, `use_surface_guiding` with Cycles' default training samples.

Every image is compared with the mean of two `zvidpt reference` halves, as in `race.py`: MSE less
the reference's own noise, and MSE x seconds. Before any comparison each Cycles configuration's
translation is checked: the mean of its images over the seeds against the reference's mean, per
channel (z from the seeds' spread and the reference's); a |z| above 4 marks a mismatch and its
figures are not race results.

With --mitsuba (`pip install mitsuba` too), Mitsuba 3 races in the same run, on the same
reference, from `race.py`'s translation of the same subset (`scalar_rgb`, `path`, box filter,
`multijitter` sampler), with its own translation check.

Writes OUT/cycles.csv and OUT/cycles.md.
"""
import math
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import toml_subset  # noqa: E402
from race import (  # noqa: E402
    mitsuba_scene_dict,
    race_arguments,
    race_mitsuba,
    race_zvidpt,
    read_exr,
    references,
    translation_check,
    write_results,
)

PEER = "Cycles"


def refuse(message):
    toml_subset.refuse(PEER, message)


def build_cycles_scene(folder, width, height, threads):
    import bpy
    from mathutils import Matrix, Vector

    cam, materials, meshes = toml_subset.read_scene(folder, PEER)
    scene = bpy.context.scene
    # The start-up scene's objects (a cube, a lamp, a camera) go.
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o, do_unlink=True)
    scene.render.engine = "CYCLES"

    def diffuse_material(name, rgb):
        m = bpy.data.materials.new(name)
        m.use_nodes = True
        nodes = m.node_tree.nodes
        nodes.clear()
        out = nodes.new("ShaderNodeOutputMaterial")
        bsdf = nodes.new("ShaderNodeBsdfDiffuse")
        bsdf.inputs["Color"].default_value = (*rgb, 1.0)
        bsdf.inputs["Roughness"].default_value = 0.0
        m.node_tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
        return m

    def emitter_material(name, radiance):
        m = bpy.data.materials.new(name)
        m.use_nodes = True
        nodes, links = m.node_tree.nodes, m.node_tree.links
        nodes.clear()
        out = nodes.new("ShaderNodeOutputMaterial")
        emission = nodes.new("ShaderNodeEmission")
        peak = max(radiance)
        emission.inputs["Color"].default_value = (*[c / peak for c in radiance], 1.0)
        emission.inputs["Strength"].default_value = peak
        black = nodes.new("ShaderNodeBsdfDiffuse")
        black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        geometry = nodes.new("ShaderNodeNewGeometry")
        mix = nodes.new("ShaderNodeMixShader")
        links.new(geometry.outputs["Backfacing"], mix.inputs["Fac"])
        links.new(emission.outputs["Emission"], mix.inputs[1])
        links.new(black.outputs["BSDF"], mix.inputs[2])
        links.new(mix.outputs["Shader"], out.inputs["Surface"])
        m.cycles.emission_sampling = "FRONT"
        return m

    made = {}

    def material_named(name, mesh, kd):
        if name not in made:
            reflectance, radiance = toml_subset.surface(materials, kd, mesh, name, PEER)
            made[name] = (emitter_material(name, radiance) if max(radiance) > 0
                          else diffuse_material(name, reflectance))
        return made[name]

    for mesh in meshes:
        obj_path = folder / mesh["obj"]
        before = set(bpy.data.objects)
        bpy.ops.wm.obj_import(filepath=str(obj_path), forward_axis="Y", up_axis="Z")
        imported = [o for o in bpy.data.objects if o not in before]
        kd = toml_subset.mtl_colours(obj_path, PEER)
        for o in imported:
            if mesh.get("reverse_winding", False):
                o.data.flip_normals()
            if "material" in mesh:
                o.data.materials.clear()
                o.data.materials.append(material_named(mesh["material"], mesh, kd))
                continue
            if not o.material_slots:
                refuse(f"{obj_path.name}: a mesh without a material")
            for slot in o.material_slots:
                if slot.material is None:
                    refuse(f"{obj_path.name}: a face without a material")
                slot.material = material_named(slot.material.name.split(".")[0], mesh, kd)

    eye, target, up = (Vector(cam[k]) for k in ("eye", "look_at", "up"))
    forward = (target - eye).normalized()
    right = forward.cross(up).normalized()
    true_up = right.cross(forward)
    rotation = Matrix((right, true_up, -forward)).transposed()
    cam_data = bpy.data.cameras.new("camera")
    cam_data.sensor_fit = "VERTICAL"
    cam_data.angle_y = math.radians(cam["fov_y"])
    cam_obj = bpy.data.objects.new("camera", cam_data)
    cam_obj.matrix_world = Matrix.Translation(eye) @ rotation.to_4x4()
    scene.collection.objects.link(cam_obj)
    scene.camera = cam_obj

    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.world = world

    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y = width or cam["width"], height or cam["height"]
    r.resolution_percentage = 100
    r.threads_mode = "FIXED"
    r.threads = threads
    r.film_transparent = False
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.image_settings.exr_codec = "ZIP"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    c = scene.cycles
    c.device = "CPU"
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.samples = 1 << 24
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    for bounces in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces",
                    "transparent_max_bounces"):
        setattr(c, bounces, 1024)
    c.volume_bounces = 0
    return scene


def cycles_render(scene, path, seconds, seed, guiding):
    import bpy

    c = scene.cycles
    c.time_limit = seconds
    c.seed = seed
    c.use_guiding = guiding
    c.use_surface_guiding = guiding
    c.use_volume_guiding = False
    scene.render.filepath = str(path)
    start = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.perf_counter() - start


def main():
    p = race_arguments(__doc__)
    p.add_argument("--resolution", default=None, help="WxH (default: the scene's)")
    p.add_argument("--mitsuba", action="store_true",
                   help="race Mitsuba 3 too, in the same run (race.py's translation of the same subset)")
    a = p.parse_args()
    folder = Path(a.scene)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    seeds = [int(s) for s in a.seeds.split(",")]
    extra = ["--threads", str(a.threads)]
    width = height = None
    if a.resolution:
        width, height = (int(x) for x in a.resolution.lower().split("x"))
        extra += ["--resolution", a.resolution]
    ref, ref_pixel_var, ref_noise = references(a.zvidpt, folder, out, a.ref_spp, extra)
    rows = race_zvidpt(a.zvidpt, folder, out, a.integrators, seeds, a.time, extra, ref, ref_noise)
    mitsuba_check = ""
    mismatched = set()
    if a.mitsuba:
        mitsuba_rows, matched, mitsuba_check = race_mitsuba(
            lambda mi: mi.load_dict(mitsuba_scene_dict(folder, out, width, height)), seeds, a.time, a.threads, ref,
            ref_pixel_var, ref_noise)
        rows += mitsuba_rows
        mitsuba_check = f" {mitsuba_check}."
        mismatched |= set() if matched else {r[:2] for r in mitsuba_rows}

    scene = build_cycles_scene(folder, width, height, a.threads)
    print(f"Cycles: sampling pattern {scene.cycles.sampling_pattern}", flush=True)
    cycles_render(scene, out / "warm-up.exr", 1.0, 0, False)  # the first render pays for set-up
    checks = {}
    for name, guiding in (("path", False), ("path guiding (Open PGL)", True)):
        images = []
        for seed in seeds:
            img = out / f"cycles-{'guiding' if guiding else 'path'}-{seed}.exr"
            secs = cycles_render(scene, img, a.time, seed, guiding)
            rgb, _ = read_exr(img)
            if rgb.shape != ref.shape:
                sys.exit(f"Cycles wrote {rgb.shape}, the reference is {ref.shape}")
            images.append(rgb)
            mse = float(((rgb - ref) ** 2).mean()) - ref_noise
            rows.append(("cycles", name, seed, secs, mse, float("nan")))
            print(f"cycles {name} seed {seed}: {secs:.2f} s, MSE {mse:.4g}", flush=True)
        matched, ratio, z = translation_check(images, ref, ref_pixel_var)
        print(f"Cycles {name} mean / reference mean: {ratio[0]:.4f}, {ratio[1]:.4f}, {ratio[2]:.4f} "
              f"(z {z[0]:.2f}, {z[1]:.2f}, {z[2]:.2f}): {'matches' if matched else 'MISMATCH'}", flush=True)
        checks[name] = (matched, ratio, z)

    preamble = (
        f"Equal time {a.time:g} s, {a.threads} threads, seeds {a.seeds}; MSE against `zvidpt reference` "
        f"(path, {a.ref_spp} spp in two independent halves) less the reference's own noise ({ref_noise:.3g}). "
        f"Cycles {scene.cycles.sampling_pattern} sampling pattern. Translation checks (image mean / reference "
        "mean per channel, z): "
        + "; ".join(f"{n}: {r[0]:.4f}, {r[1]:.4f}, {r[2]:.4f} (|z| <= {np.abs(z).max():.2f}, "
                    f"{'matches' if m else 'MISMATCH'})" for n, (m, r, z) in checks.items()) + "."
        + mitsuba_check)
    mismatched |= {("cycles", n) for n, (m, _, _) in checks.items() if not m}
    write_results(out, "cycles", rows, preamble, mismatched)


if __name__ == "__main__":
    main()
