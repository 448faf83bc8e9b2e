"""A .glb's JSON edited in place, for tests of what a glTF file says that trimesh cannot write (extensions,
normal texture scales, out-of-range values, animations)."""

import json
import struct

import numpy as np


def edit_glb_json(data: bytes, edit) -> bytes:
    """The .glb ``data`` with its JSON chunk passed through ``edit`` (a function that changes the parsed tree)."""
    length = struct.unpack_from("<I", data, 12)[0]
    tree = json.loads(data[20:20 + length])
    edit(tree)
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + data[20 + length:]
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


COMPONENT_TYPES = {np.dtype(np.uint8): 5121, np.dtype(np.uint16): 5123, np.dtype(np.float32): 5126}


def with_accessors(data: bytes, arrays: list, edit) -> bytes:
    """The .glb ``data`` with ``arrays`` (float32, or uint8/uint16 where given so) appended to its binary chunk, each
    as a bufferView and an accessor of its own (SCALAR, VEC2, VEC3, VEC4 or MAT4 by its columns), then its JSON passed
    through ``edit(tree, first)``, ``first`` the first new accessor's index."""
    length = struct.unpack_from("<I", data, 12)[0]
    tree = json.loads(data[20:20 + length])
    binary_at = 20 + length
    binary = bytearray(data[binary_at + 8:binary_at + 8 + struct.unpack_from("<I", data, binary_at)[0]])
    first = len(tree["accessors"])
    for array in arrays:
        array = np.asarray(array)
        array = (array if array.dtype in COMPONENT_TYPES else array.astype(np.float32)).reshape(len(array), -1)
        binary += b"\0" * (-len(binary) % 4)
        tree["bufferViews"].append({"buffer": 0, "byteOffset": len(binary), "byteLength": array.nbytes})
        tree["accessors"].append({"bufferView": len(tree["bufferViews"]) - 1,
                                  "componentType": COMPONENT_TYPES[array.dtype], "count": len(array),
                                  "type": {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4", 16: "MAT4"}[array.shape[1]]})
        binary += array.tobytes()
    binary += b"\0" * (-len(binary) % 4)
    tree["buffers"][0]["byteLength"] = len(binary)
    edit(tree, first)
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    body = (struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(binary), b"BIN\0")
            + bytes(binary))
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body
