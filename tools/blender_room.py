# blender_room.py: makes tests/data/blender_room.gltf the way a Blender user would, with
# Blender's own glTF exporter. Run headless:
#   blender -b --factory-startup --python tools/blender_room.py -- tests/data/blender_room.gltf
# A room modelled from the default kind of cube (normals out, as Blender makes them), a
# window cut into one wall by a boolean (on a zero-thickness room the cut is a niche), a
# table (a top and four legs, cubes), a point light below the ceiling and a camera
# inside. The materials are Principled BSDF with back-face culling off, which the
# exporter writes as doubleSided: true (its default for every material). Quads are
# restored after the boolean (triangulate, then join triangles into quads), since the
# bake works on quads. Not run by the tests (Blender is not a build dependency); the
# exported file is committed.
import sys

import bpy

out = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else "blender_room.gltf"

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene


def material(name, rgb, double_sided=True):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*rgb, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Metallic"].default_value = 0.0
    bsdf.inputs["Specular"].default_value = 0.0
    m.use_backface_culling = not double_sided
    return m


def box(name, center, size, mat):
    bpy.ops.mesh.primitive_cube_add(size=1, location=center)
    o = bpy.context.active_object
    o.name = name
    o.scale = size
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    o.data.materials.append(mat)
    return o


def requad(o):
    bpy.context.view_layer.objects.active = o
    o.select_set(True)
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.mesh.quads_convert_to_tris(quad_method="BEAUTY", ngon_method="BEAUTY")
    bpy.ops.mesh.tris_convert_to_quads(face_threshold=0.01, shape_threshold=3.14159)
    bpy.ops.object.mode_set(mode="OBJECT")
    o.select_set(False)


wall = material("Walls", (0.7, 0.7, 0.7))
wood = material("Table", (0.5, 0.35, 0.2))

# The room: 4 x 5 m, 2.6 m high (Blender is Z-up; the exporter writes Y-up).
room = box("Room", (0, 0, 1.3), (4, 5, 2.6), wall)
# The window: a box through the wall at x = +2, cut away by a boolean (Exact solver).
cutter = box("WindowCutter", (2.0, 0.3, 1.4), (0.4, 1.4, 1.0), wall)
mod = room.modifiers.new("Window", "BOOLEAN")
mod.operation = "DIFFERENCE"
mod.solver = "EXACT"
mod.object = cutter
bpy.context.view_layer.objects.active = room
bpy.ops.object.modifier_apply(modifier="Window")
bpy.data.objects.remove(cutter, do_unlink=True)
requad(room)

# The table: a top and four legs.
box("TableTop", (-0.5, -0.6, 0.75), (1.2, 0.8, 0.05), wood)
for i, (x, y) in enumerate([(-1.05, -0.95), (0.05, -0.95), (-1.05, -0.25), (0.05, -0.25)]):
    box("TableLeg%d" % i, (x, y, 0.3625), (0.06, 0.06, 0.725), wood)

# A point light below the ceiling.
ld = bpy.data.lights.new("Lamp", type="POINT")
ld.energy = 1.0  # W; the exporter writes 54.4 cd
ld.shadow_soft_size = 0.0
lamp = bpy.data.objects.new("Lamp", ld)
lamp.location = (-0.3, 0.5, 2.2)
scene.collection.objects.link(lamp)

# A camera inside, near the wall opposite the window, looking at it.
cd = bpy.data.cameras.new("Camera")
cd.lens_unit = "FOV"
cd.angle = 1.2
cam = bpy.data.objects.new("Camera", cd)
cam.location = (-1.8, -2.2, 1.5)
scene.collection.objects.link(cam)
target = bpy.data.objects.new("Target", None)
target.location = (2.0, 0.3, 1.1)
scene.collection.objects.link(target)
c = cam.constraints.new("TRACK_TO")
c.target = target
c.track_axis = "TRACK_NEGATIVE_Z"
c.up_axis = "UP_Y"
bpy.context.view_layer.update()
mw = cam.matrix_world.copy()
cam.constraints.remove(c)
cam.matrix_world = mw
bpy.data.objects.remove(target, do_unlink=True)
scene.camera = cam

bpy.ops.export_scene.gltf(filepath=out, export_format="GLTF_EMBEDDED", export_lights=True,
                          export_cameras=True, export_apply=True, export_yup=True)
print("wrote", out)
