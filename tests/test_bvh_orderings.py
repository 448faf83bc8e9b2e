"""ordered_threaded_nodes (wgpu_rt/accel/bvh.py): one depth-first copy of the threaded BVH per direction
octant, each a valid stackless layout of the same nodes with the child nearer along the octant first.
(That walks of every copy find what brute force finds is checked through the GPU in test_bvh.py and
test_traversal.py, whose random rays run in every octant.)"""

import numpy as np

from wgpu_rt.accel.bvh import ORDERINGS, build_bvh, ordered_threaded_nodes, threaded_nodes


def _record_keys(nodes: np.ndarray) -> list[bytes]:
    return sorted(n["lo"].tobytes() + n["hi"].tobytes() + n["triangles"].tobytes() for n in nodes)


def _check_subtree(copy: np.ndarray, at: int, signs: np.ndarray) -> None:
    """Recursively: children follow their parent, inside its box, nearer (along signs) first, and the
    skips close each subtree where its parent's closes."""
    end = int(copy["skip"][at])
    if end == at + 1:
        return
    first, second = at + 1, int(copy["skip"][at + 1])
    assert second < end and int(copy["skip"][second]) == end, "a subtree is not two children"
    for child in (first, second):
        assert np.all(copy["lo"][child] >= copy["lo"][at]) and np.all(copy["hi"][child] <= copy["hi"][at])
        _check_subtree(copy, child, signs)
    center = 0.5 * (copy["lo"].astype(np.float64) + copy["hi"].astype(np.float64))
    assert center[first] @ signs <= center[second] @ signs + 1e-12, "the farther child comes first"


def test_each_octant_copy_is_a_near_first_layout_of_the_same_nodes():
    rng = np.random.default_rng(4)
    triangles = rng.uniform(-1, 1, (900, 1, 3)) + rng.normal(0, 0.05, (900, 3, 3))
    bvh = build_bvh(triangles.astype(np.float32))
    copies = ordered_threaded_nodes(bvh).reshape(ORDERINGS, bvh.node_count)
    left_first = threaded_nodes(bvh)
    assert copies.dtype == left_first.dtype
    differs = 0
    for octant, copy in enumerate(copies):
        assert _record_keys(copy) == _record_keys(left_first)
        assert copy["skip"][0] == bvh.node_count
        signs = np.where([octant >> axis & 1 for axis in range(3)], -1.0, 1.0)
        _check_subtree(copy, 0, signs)
        differs += not np.array_equal(copy, left_first)
    assert differs >= ORDERINGS // 2, "the octants should reorder the tree"
