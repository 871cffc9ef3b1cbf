# blender_smooth.py: makes tests/data/blender_smooth.gltf (+ .bin), curved meshes with
# smooth shading as a Blender user makes them (issue 21: curved surfaces look curved),
# exported unmodified by Blender's glTF exporter with its vertex normals (glTF NORMAL).
# Run headless:
#   blender -b --factory-startup --python tools/blender_smooth.py -- tests/data/blender_smooth.gltf
# A 1 m Cornell box (five planes, red left and green right wall, open at the front)
# holding a UV sphere of 32 segments and 16 rings (Shade Smooth) and Suzanne (Shade
# Smooth, decimated to a fifth so that the scene bakes in minutes on 2 cores), and a cube
# left flat (Shade Flat: its edges are creases, where the normals split). Materials as
# tools/blender_shapes.py's: Principled BSDF, roughness 1, metallic 0, single-sided.
# Blender is not a build dependency: the exported files are committed.
import sys

import bpy

out = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else "blender_smooth.gltf"

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene


def material(name, rgb):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*rgb, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Metallic"].default_value = 0.0
    bsdf.inputs["Specular"].default_value = 0.0
    m.use_backface_culling = True
    return m


def finish(o, name, mat):
    o.name = name
    o.data.materials.append(mat)
    return o


def apply_modifiers(o):
    bpy.context.view_layer.objects.active = o
    for m in list(o.modifiers):
        bpy.ops.object.modifier_apply(modifier=m.name)


white = material("White", (0.75, 0.75, 0.75))
red = material("Red", (0.63, 0.065, 0.05))
green = material("Green", (0.14, 0.45, 0.09))

walls = [("Floor", (0, 0, 0), (0, 0, 0), white), ("Ceiling", (0, 0, 1), (3.14159265, 0, 0), white),
         ("BackWall", (0, 0.5, 0.5), (1.57079633, 0, 0), white),
         ("LeftWall", (-0.5, 0, 0.5), (0, 1.57079633, 0), red),
         ("RightWall", (0.5, 0, 0.5), (0, -1.57079633, 0), green)]
for name, loc, rot, mat in walls:
    bpy.ops.mesh.primitive_plane_add(size=1, location=loc, rotation=rot)
    finish(bpy.context.active_object, name, mat)

bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=0.17, location=(-0.2, 0.15, 0.17))
sphere = finish(bpy.context.active_object, "UVSphere", white)
bpy.ops.object.shade_smooth()

bpy.ops.mesh.primitive_cube_add(size=0.2, location=(0.22, 0.05, 0.1))
finish(bpy.context.active_object, "FlatCube", white)
bpy.ops.object.shade_flat()

bpy.ops.mesh.primitive_monkey_add(size=0.24, location=(0.22, 0.05, 0.31))
suzanne = finish(bpy.context.active_object, "Suzanne", white)
dec = suzanne.modifiers.new("Decimate", "DECIMATE")
dec.ratio = 0.2
apply_modifiers(suzanne)
bpy.ops.object.shade_smooth()

ld = bpy.data.lights.new("Lamp", type="POINT")
ld.energy = 0.05
ld.shadow_soft_size = 0.0
lamp = bpy.data.objects.new("Lamp", ld)
lamp.location = (0.05, -0.1, 0.85)
scene.collection.objects.link(lamp)

cd = bpy.data.cameras.new("Camera")
cd.lens_unit = "FOV"
cd.angle = 1.1
cam = bpy.data.objects.new("Camera", cd)
cam.location = (0, -1.9, 0.5)
cam.rotation_euler = (1.57079633, 0, 0)
scene.collection.objects.link(cam)
scene.camera = cam

bpy.ops.export_scene.gltf(filepath=out, export_format="GLTF_SEPARATE", export_lights=True,
                          export_cameras=True, export_apply=True, export_yup=True)
print("wrote", out)
