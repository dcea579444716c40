"""Run inside Blender's Python (bpy): import a USD stage, report what Blender made of it, render a frame.

    python blender_check.py STAGE.usdc REPORT.json FRAMES RENDER.png RENDER_FRAME WxH

REPORT.json gets, per frame in FRAMES (comma-separated), the world matrix of every instance of
the imported PointInstancer (by instance index) and the cloth's vertex positions, plus the scene's
frame range and the camera's field of view. Only bpy and the standard library are used here, so
this script runs in its own process, apart from the pxr of the test that calls it.
"""

from __future__ import annotations

import json
import math
import sys
import time

import bpy


def instances(depsgraph) -> dict[int, list[list[float]]]:
    """Instance index -> 4 x 4 world matrix (rows), for instances of the point cloud 'Bodies'."""
    out = {}
    for inst in depsgraph.object_instances:
        if inst.is_instance and inst.parent is not None and inst.parent.name == "Bodies":
            out[int(inst.persistent_id[1])] = [list(row) for row in inst.matrix_world]
    return out


def displaycolor_material(name: str):
    """A material whose base colour is the mesh's `displayColor` attribute (as the file gives it)."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    bsdf = nodes.get("Principled BSDF")
    attr = nodes.new("ShaderNodeAttribute")
    attr.attribute_name = "displayColor"
    mat.node_tree.links.new(attr.outputs["Color"], bsdf.inputs["Base Color"])
    bsdf.inputs["Roughness"].default_value = 0.6
    return mat


def main(argv: list[str]) -> int:
    stage, report_path, frames, render_path, render_frame, size = argv
    frames = [int(f) for f in frames.split(",")]
    width, height = (int(v) for v in size.split("x"))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    start = time.perf_counter()
    bpy.ops.wm.usd_import(filepath=stage)
    report = {"import_seconds": time.perf_counter() - start}
    scene = bpy.context.scene
    report["frame_start"], report["frame_end"] = scene.frame_start, scene.frame_end
    camera = bpy.data.objects.get("Camera")
    report["camera_fov_y"] = math.degrees(camera.data.angle_y) if camera else None
    report["frames"] = {}
    for f in frames:
        scene.frame_set(f)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        cloth = bpy.data.objects["Cloth"].evaluated_get(depsgraph)
        report["frames"][str(f)] = {
            "instances": instances(depsgraph),
            "cloth": [list(cloth.matrix_world @ v.co) for v in cloth.data.vertices],
        }

    # render: the imported camera, a sun along Tumble's light direction, the file's colours
    scene.frame_set(int(render_frame))
    scene.camera = camera
    for obj in bpy.data.objects:
        if obj.type == "MESH" and "displayColor" in obj.data.attributes:
            obj.data.materials.clear()
            obj.data.materials.append(displaycolor_material(f"{obj.name}_color"))
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    sun.data.angle = math.radians(3.0)
    scene.collection.objects.link(sun)
    light = (0.6, -0.15, 1.0)  # tumble.render.Renderer.light_direction (towards the sun)
    sun.rotation_mode = "QUATERNION"
    import mathutils

    sun.rotation_quaternion = mathutils.Vector(light).to_track_quat("Z", "Y")
    world = bpy.data.worlds.new("Sky")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.55, 0.65, 0.8, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.6
    scene.world = world
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 16
    scene.cycles.use_denoising = False
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = render_path
    start = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    report["render_seconds"] = time.perf_counter() - start
    with open(report_path, "w", encoding="utf-8") as f:
        json.dump(report, f)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
