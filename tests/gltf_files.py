"""A .glb's JSON edited in place, for tests of what a glTF file says that trimesh cannot write (extensions,
normal texture scales, out-of-range values)."""

import json
import struct


def edit_glb_json(data: bytes, edit) -> bytes:
    """The .glb ``data`` with its JSON chunk passed through ``edit`` (a function that changes the parsed tree)."""
    length = struct.unpack_from("<I", data, 12)[0]
    tree = json.loads(data[20:20 + length])
    edit(tree)
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + data[20 + length:]
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body
