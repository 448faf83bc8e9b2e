"""The acceleration structure: BVH build and threaded nodes (``bvh``), a frame's geometry flattened,
uploaded and its traversal chosen per adapter (``geometry``), and ray queries against it (``ray_query``)."""
