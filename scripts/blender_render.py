"""Render an assetfield dataset again with another renderer: Blender's Cycles.

    blender -b --factory-startup -P scripts/blender_render.py -- DATA OUT [--samples 64] [--sun-deg 8]

DATA is a dataset written by `assetfield synth ... --mesh` (its mesh/scene.obj, scene.mtl
and textures, its transforms_{train,test}.json, gt_layout.json, synth.json). OUT receives
the same cameras rendered by Cycles (path tracing: a sun with a soft penumbra, sky light,
bounced light, shadows, Blender's own texture filtering) as RGBA PNGs with a transparent
background, with copies of the transforms, the ground truth and synth.json: a dataset the
rest of the pipeline reads like any other. The geometry, cameras and ground truth are the
scene's own; only the look differs, so that the detector is measured on a renderer it was
not made with.

Written to a temporary folder next to OUT and renamed into place when complete.
"""

import json
import math
import os
import shutil
import sys

import bpy
from mathutils import Matrix


def parse(argv):
    args = argv[argv.index("--") + 1:] if "--" in argv else []
    if len(args) < 2:
        sys.exit(__doc__)
    opts = {"data": args[0], "out": args[1], "samples": 64, "sun_deg": 8.0}
    rest = args[2:]
    while rest:
        key = rest.pop(0)
        if key == "--samples":
            opts["samples"] = int(rest.pop(0))
        elif key == "--sun-deg":
            opts["sun_deg"] = float(rest.pop(0))
        else:
            sys.exit(f"unknown option {key}\n{__doc__}")
    return opts


def setup(data, samples, sun_deg, width, height):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    obj = os.path.join(data, "mesh", "scene.obj")
    if not os.path.exists(obj):
        sys.exit(f"{obj} not found: synthesise the dataset with `assetfield synth ... --mesh`")
    # the file is in world coordinates with Z up already: import it as it is
    bpy.ops.wm.obj_import(filepath=obj, forward_axis="Y", up_axis="Z")
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 4
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = True
    # keep the synced scene (its BVH) between the views: only the camera moves
    scene.render.use_persistent_data = True
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.view_settings.view_transform = "Standard"
    # light: a sun from the same quarter as the ground-truth renderer's light, with a soft
    # penumbra, and a uniform sky for the shadowed sides
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 3.0
    sun.data.angle = math.radians(sun_deg)
    sun.rotation_euler = (math.radians(40.0), 0.0, math.radians(125.0))
    scene.collection.objects.link(sun)
    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs[1].default_value = 0.8
    scene.world = world
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene, cam


def main():
    o = parse(sys.argv)
    data, out = os.path.abspath(o["data"]), os.path.abspath(o["out"])
    if os.path.exists(out):
        sys.exit(f"{out} exists: remove it first")
    with open(os.path.join(data, "synth.json")) as f:
        res = json.load(f)["config"]["resolution"]
    scene, cam = setup(data, o["samples"], o["sun_deg"], res, res)
    tmp = out + ".partial"
    shutil.rmtree(tmp, ignore_errors=True)
    os.makedirs(tmp)
    for split in ("train", "test"):
        name = f"transforms_{split}.json"
        with open(os.path.join(data, name)) as f:
            transforms = json.load(f)
        cam.data.sensor_fit = "HORIZONTAL"
        cam.data.angle_x = transforms["camera_angle_x"]
        for k, frame in enumerate(transforms["frames"]):
            # NeRF-synthetic poses are Blender's: camera-to-world, looking down -Z
            cam.matrix_world = Matrix(frame["transform_matrix"])
            scene.render.filepath = os.path.join(tmp, frame["file_path"].lstrip("./") + ".png")
            bpy.ops.render.render(write_still=True)
            print(f"{split} {k + 1}/{len(transforms['frames'])}", flush=True)
        shutil.copy(os.path.join(data, name), os.path.join(tmp, name))
    for extra in ("gt_layout.json", "synth.json", "layout.png", "scene.ron"):
        if os.path.exists(os.path.join(data, extra)):
            shutil.copy(os.path.join(data, extra), os.path.join(tmp, extra))
    with open(os.path.join(tmp, "renderer.json"), "w") as f:
        json.dump({"renderer": "blender-cycles", "blender": bpy.app.version_string,
                   "samples": o["samples"], "sun_angle_deg": o["sun_deg"], "source": data}, f,
                  indent=2)
    os.rename(tmp, out)
    print(f"wrote {out}")


main()
