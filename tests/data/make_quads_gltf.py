#!/usr/bin/env python3
"""Writes the tiny glTF test scenes: `quads` three ways, quads.gltf (+ quads.bin, checker.png
beside it), quads_embedded.gltf (data URIs) and quads.glb; and cards.glb (see its notes below).
Run from this directory; the outputs are committed, so this only documents (and can regenerate)
them.

World, in metres: a camera rig at x = +0.5 whose camera child is turned 90 degrees about +y, so
it looks down world -x with world -z to its right. A "stage" node at x = -1 holds quads facing +x:
  near   local x =  0   (1.5 m from the camera) 0.2 m square, base colour (0.8, 0.1, 0.1), single-sided
  chart  local x = -1   (2.5 m) 0.6 m square, a 4x4 nearest/repeat texture, base colour factor 1
  back   local x = -2   (3.5 m) 1 m square facing AWAY from the camera, single-sided: never seen
  wall   local x = -3   (4.5 m) 4 m square, black base, emissive (0.2, 0.3, 0.5) x strength 2
The near quad is a 2 m unit quad scaled by 0.1 in its node (transform composition).
"""
import base64, json, struct, zlib

def png(width, height, rows):
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    raw = b"".join(b"\0" + bytes(row) for row in rows)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))

# Texel (column i, row j) = sRGB bytes (10 + 60 i, 10 + 60 j, 200).
checker = png(4, 4, [[c for i in range(4) for c in (10 + 60 * i, 10 + 60 * j, 200)] for j in range(4)])

def quad(h, facing_camera=True):
    # Corners in (right, up) = (-z, y) order, counter-clockwise seen from +x.
    corners = [(0.0, -h, h), (0.0, -h, -h), (0.0, h, -h), (0.0, h, h)]
    uvs = [(0.0, 1.0), (1.0, 1.0), (1.0, 0.0), (0.0, 0.0)]
    indices = [0, 1, 2, 0, 2, 3] if facing_camera else [0, 2, 1, 0, 3, 2]
    return corners, uvs, indices

binary = bytearray()
views, accessors, meshes = [], [], []

def add_view(data, target=None):
    while len(binary) % 4:
        binary.append(0)
    view = {"buffer": 0, "byteOffset": len(binary), "byteLength": len(data)}
    if target:
        view["target"] = target
    binary.extend(data)
    views.append(view)
    return len(views) - 1

def add_accessor(view, component, count, kind, extra=None):
    accessors.append({"bufferView": view, "componentType": component, "count": count, "type": kind, **(extra or {})})
    return len(accessors) - 1

def add_mesh(corners, uvs, indices, material):
    pos = add_accessor(add_view(b"".join(struct.pack("<3f", *c) for c in corners), 34962), 5126, 4, "VEC3",
                       {"min": [min(c[k] for c in corners) for k in range(3)],
                        "max": [max(c[k] for c in corners) for k in range(3)]})
    uv = add_accessor(add_view(b"".join(struct.pack("<2f", *t) for t in uvs), 34962), 5126, 4, "VEC2")
    ind = add_accessor(add_view(struct.pack("<6H", *indices), 34963), 5123, 6, "SCALAR")
    meshes.append({"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "indices": ind,
                                    "material": material}]})
    return len(meshes) - 1

near = add_mesh(*quad(1.0), 0)
chart = add_mesh(*quad(0.3), 1)
back = add_mesh(*quad(0.5, facing_camera=False), 0)
wall = add_mesh(*quad(2.0), 2)
half = 0.5 ** 0.5
document = {
    "asset": {"version": "2.0", "generator": "lensbake tests/data/make_quads_gltf.py"},
    "extensionsUsed": ["KHR_materials_emissive_strength"],
    "scene": 0,
    "scenes": [{"nodes": [0, 2]}],
    "nodes": [
        {"name": "rig", "translation": [0.5, 0.0, 0.0], "children": [1]},
        {"name": "camera", "rotation": [0.0, half, 0.0, half], "camera": 0},
        {"name": "stage", "translation": [-1.0, 0.0, 0.0], "children": [3, 4, 5, 6]},
        {"name": "near", "mesh": near, "scale": [1.0, 0.1, 0.1]},
        {"name": "chart", "mesh": chart, "translation": [-1.0, 0.0, 0.0]},
        {"name": "back", "mesh": back, "translation": [-2.0, 0.0, 0.0]},
        {"name": "wall", "mesh": wall, "translation": [-3.0, 0.0, 0.0]},
    ],
    "cameras": [{"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.01}}],
    "meshes": meshes,
    "materials": [
        {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.1, 0.1, 1.0]}},
        {"name": "checker", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
        {"name": "glow", "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0]},
         "emissiveFactor": [0.2, 0.3, 0.5],
         "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2.0}}},
    ],
    "textures": [{"source": 0, "sampler": 0}],
    "samplers": [{"magFilter": 9728, "minFilter": 9728, "wrapS": 10497, "wrapT": 10497}],
    "bufferViews": views,
    "accessors": accessors,
}

def write_json(name, doc):
    with open(name, "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")

adjacent = dict(document, buffers=[{"uri": "quads.bin", "byteLength": len(binary)}],
                images=[{"uri": "checker.png"}])
write_json("quads.gltf", adjacent)
with open("quads.bin", "wb") as f:
    f.write(binary)
with open("checker.png", "wb") as f:
    f.write(checker)

data_uri = lambda mime, data: f"data:{mime};base64," + base64.b64encode(data).decode()
embedded = dict(document, buffers=[{"uri": data_uri("application/octet-stream", bytes(binary)),
                                    "byteLength": len(binary)}],
                images=[{"uri": data_uri("image/png", checker)}])
write_json("quads_embedded.gltf", embedded)

def write_glb(name, doc):
    """Binary glTF: the JSON chunk, then the current `binary` as the BIN chunk (buffer 0)."""
    while len(binary) % 4:
        binary.append(0)
    doc = dict(doc, bufferViews=views, accessors=accessors, buffers=[{"byteLength": len(binary)}])
    json_chunk = json.dumps(doc).encode()
    json_chunk += b" " * (-len(json_chunk) % 4)
    glb = (struct.pack("<I4s", len(json_chunk), b"JSON") + json_chunk
           + struct.pack("<I4s", len(binary), b"BIN\0") + bytes(binary))
    with open(name, "wb") as f:
        f.write(struct.pack("<4sII", b"glTF", 2, 12 + len(glb)) + glb)

image_view = add_view(checker)
write_glb("quads.glb", dict(document, images=[{"bufferView": image_view, "mimeType": "image/png"}]))

# cards.glb: twelve double-sided 0.4 m cards facing the camera (default view: the origin looking
# down -z) at 3.0, 3.1, ..., 4.1 m, each shifted 2 cm right of the one before, in front of a
# 6 m grey wall at 5 m. Plain peeling needs a layer per card where they overlap; umbra peeling
# skips the cards hidden behind a nearer card from the whole entrance pupil.
binary = bytearray()
views, accessors, meshes = [], [], []

def facing_z(h):
    # Counter-clockwise seen from +z (the camera), v down the image.
    corners = [(-h, -h, 0.0), (h, -h, 0.0), (h, h, 0.0), (-h, h, 0.0)]
    uvs = [(0.0, 1.0), (1.0, 1.0), (1.0, 0.0), (0.0, 0.0)]
    return corners, uvs, [0, 1, 2, 0, 2, 3]

card = add_mesh(*facing_z(0.2), 0)
back_wall = add_mesh(*facing_z(3.0), 1)
nodes = [{"name": f"card {k}", "mesh": card, "translation": [0.02 * k, 0.0, -3.0 - 0.1 * k]} for k in range(12)]
nodes.append({"name": "wall", "mesh": back_wall, "translation": [0.0, 0.0, -5.0]})
cards = {
    "asset": {"version": "2.0", "generator": "lensbake tests/data/make_quads_gltf.py"},
    "scene": 0,
    "scenes": [{"nodes": list(range(len(nodes)))}],
    "nodes": nodes,
    "meshes": meshes,
    "materials": [
        {"name": "card", "doubleSided": True, "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.7, 0.2, 1.0]}},
        {"name": "wall", "pbrMetallicRoughness": {"baseColorFactor": [0.3, 0.3, 0.35, 1.0]}},
    ],
}
write_glb("cards.glb", cards)
