"""Blender's side of the punctual-light check (tests/blender_reference.rs).

For each light type (point, spot, sun) build a grey diffuse floor lit by that one light, seen by
a camera, in an otherwise black world; render it with Cycles into <out>/<case>.exr (linear) and
export it with Blender's glTF exporter (lighting mode "Standard", photometric units) into
<out>/<case>/scene.gltf. Usage: python lights.py OUT_DIR (python = a venv with the bpy module).
"""
import math
import os
import sys

import bpy

WIDTH, HEIGHT, SAMPLES = 64, 48, 64


def floor_material():
    mat = bpy.data.materials.new("floor")
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Metallic"].default_value = 0.0
    bsdf.inputs["Specular IOR Level"].default_value = 0.0  # diffuse only, in both renderers
    return mat


def build(case):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = SAMPLES
    scene.cycles.use_denoising = False
    scene.cycles.seed = 1
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.world = world

    bpy.ops.mesh.primitive_plane_add(size=10.0, location=(0.0, 0.0, 0.0))
    bpy.context.object.data.materials.append(floor_material())

    cam_data = bpy.data.cameras.new("camera")
    cam_data.lens = 30.0
    cam = bpy.data.objects.new("camera", cam_data)
    cam.location = (0.0, -4.0, 3.0)
    cam.rotation_euler = (math.radians(53.0), 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam

    if case == "point":
        light = bpy.data.lights.new("light", "POINT")
        light.energy = 150.0  # W
        light.shadow_soft_size = 0.0
        location, rotation = (0.5, 0.0, 2.0), (0.0, 0.0, 0.0)
    elif case == "spot":
        light = bpy.data.lights.new("light", "SPOT")
        light.energy = 300.0  # W, as if it were a point light
        light.shadow_soft_size = 0.0
        light.spot_size = math.radians(70.0)
        # a narrow blend: glTF's cone falloff (squared, linear in cos) is not Cycles' smoothstep
        light.spot_blend = 0.02
        location, rotation = (0.0, 0.5, 2.5), (0.0, 0.0, 0.0)  # pointing down
    elif case == "sun":
        light = bpy.data.lights.new("light", "SUN")
        light.energy = 2.0  # W/m^2
        light.angle = 0.0
        location, rotation = (0.0, 0.0, 5.0), (math.radians(30.0), math.radians(10.0), 0.0)
    else:
        raise ValueError(case)
    if hasattr(light, "use_soft_falloff"):
        light.use_soft_falloff = False
    obj = bpy.data.objects.new("light", light)
    obj.location = location
    obj.rotation_euler = rotation
    scene.collection.objects.link(obj)
    return scene


def main():
    out = sys.argv[-1]
    os.makedirs(out, exist_ok=True)
    for case in ["point", "spot", "sun"]:
        scene = build(case)
        scene.render.image_settings.file_format = "OPEN_EXR"
        scene.render.image_settings.color_depth = "32"
        scene.render.filepath = os.path.join(out, case + ".exr")
        bpy.ops.render.render(write_still=True)
        folder = os.path.join(out, case)
        os.makedirs(folder, exist_ok=True)
        bpy.ops.export_scene.gltf(
            filepath=os.path.join(folder, "scene.gltf"),
            export_format="GLTF_SEPARATE",
            export_cameras=True,
            export_lights=True,
            export_import_convert_lighting_mode="SPEC",
        )
        print(f"{case}: {scene.render.filepath} and {folder}/scene.gltf", flush=True)


main()
