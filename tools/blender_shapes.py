# blender_shapes.py: makes tests/data/blender_shapes.gltf (+ .bin) the way a Blender user
# would, from Blender's own primitives and modifiers, exported unmodified by Blender's glTF
# exporter (issue 21: any triangle mesh loads and bakes). Run headless:
#   blender -b --factory-startup --python tools/blender_shapes.py -- tests/data/blender_shapes.gltf
# A 1 m Cornell box (five planes, red left and green right wall, open at the front) holding
# a UV sphere, a cylinder, a cone, a torus, Suzanne, a bevelled cube and a block with a
# hole cut by a boolean (Exact solver). Nothing is re-quadded: the exporter triangulates,
# and the loader pairs what pairs and keeps the rest as triangles. Segment counts are low
# (sphere 12 x 6, cylinder and cone 12, torus 12 x 6) and Suzanne is decimated to about a
# tenth (a Decimate modifier) so that the scene bakes in minutes on 2 cores. Materials
# are Principled BSDF, roughness 1, metallic 0, back-face culling on (single-sided:
# doubleSided would double every element). Blender is not a build dependency: the
# exported files are committed; tests/triangles.sh reruns the script when Blender is
# installed and checks that its output loads the same.
import sys

import bpy

out = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else "blender_shapes.gltf"

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
blue = material("Blue", (0.2, 0.3, 0.7))
yellow = material("Yellow", (0.8, 0.7, 0.2))

# The box (Blender is Z-up; the exporter writes Y-up): x and y in [-0.5, 0.5], z in [0, 1],
# open towards -y where the camera is. A plane faces +z; each is turned to face inwards.
walls = [("Floor", (0, 0, 0), (0, 0, 0), white), ("Ceiling", (0, 0, 1), (3.14159265, 0, 0), white),
         ("BackWall", (0, 0.5, 0.5), (1.57079633, 0, 0), white),
         ("LeftWall", (-0.5, 0, 0.5), (0, 1.57079633, 0), red),
         ("RightWall", (0.5, 0, 0.5), (0, -1.57079633, 0), green)]
for name, loc, rot, mat in walls:
    bpy.ops.mesh.primitive_plane_add(size=1, location=loc, rotation=rot)
    finish(bpy.context.active_object, name, mat)

bpy.ops.mesh.primitive_uv_sphere_add(segments=12, ring_count=6, radius=0.12, location=(-0.28, 0.25, 0.12))
finish(bpy.context.active_object, "UVSphere", white)

bpy.ops.mesh.primitive_cylinder_add(vertices=12, radius=0.08, depth=0.3, location=(0.3, 0.3, 0.15))
finish(bpy.context.active_object, "Cylinder", blue)

bpy.ops.mesh.primitive_cone_add(vertices=12, radius1=0.1, depth=0.25, location=(0.02, 0.32, 0.125))
finish(bpy.context.active_object, "Cone", yellow)

bpy.ops.mesh.primitive_torus_add(major_segments=12, minor_segments=6, major_radius=0.1, minor_radius=0.035,
                                 location=(-0.27, -0.18, 0.035))
finish(bpy.context.active_object, "Torus", yellow)

# A bevelled cube (Bevel modifier, 2 segments) with Suzanne sitting on it, decimated.
bpy.ops.mesh.primitive_cube_add(size=0.2, location=(0.25, -0.12, 0.1))
cube = finish(bpy.context.active_object, "BevelledCube", white)
bev = cube.modifiers.new("Bevel", "BEVEL")
bev.width = 0.02
bev.segments = 2
apply_modifiers(cube)

bpy.ops.mesh.primitive_monkey_add(size=0.22, location=(0.25, -0.12, 0.29))
suzanne = finish(bpy.context.active_object, "Suzanne", white)
dec = suzanne.modifiers.new("Decimate", "DECIMATE")
dec.ratio = 0.1
apply_modifiers(suzanne)

# A block with a round hole along y, cut by a boolean (Exact solver).
bpy.ops.mesh.primitive_cube_add(size=1, location=(-0.05, -0.3, 0.08))
block = finish(bpy.context.active_object, "BooleanBlock", white)
block.scale = (0.3, 0.14, 0.16)
bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
bpy.ops.mesh.primitive_cylinder_add(vertices=12, radius=0.05, depth=0.3, location=(-0.05, -0.3, 0.08),
                                    rotation=(1.57079633, 0, 0))
cutter = bpy.context.active_object
mod = block.modifiers.new("Hole", "BOOLEAN")
mod.operation = "DIFFERENCE"
mod.solver = "EXACT"
mod.object = cutter
apply_modifiers(block)
bpy.data.objects.remove(cutter, do_unlink=True)

# A point light under the ceiling (the exporter turns W into cd).
ld = bpy.data.lights.new("Lamp", type="POINT")
ld.energy = 0.05
ld.shadow_soft_size = 0.0
lamp = bpy.data.objects.new("Lamp", ld)
lamp.location = (0, 0, 0.85)
scene.collection.objects.link(lamp)

# A camera in front of the open side, looking in.
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
