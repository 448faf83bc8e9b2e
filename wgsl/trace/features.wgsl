// Scene-feature switches of the path-tracing kernel. The renderer sets them per scene as pipeline
// override constants; code under a false switch is constant-folded away when the pipeline is created,
// so a diffuse-only scene never pays for glass, metal, light-type branching or motion vectors.

override HAS_DIELECTRIC: bool = true;       // any smooth or rough glass, or a plastic's coat
override HAS_CONDUCTOR: bool = true;        // any smooth or rough metal
override HAS_AREA_LIGHTS: bool = true;      // any emissive triangle
override HAS_ANALYTIC_LIGHTS: bool = true;  // any point or directional light, or a non-black background
override HAS_EMITTER_GROUPS: bool = true;   // lights in more than one emitter group (trace/emitters.wgsl)
override HAS_MOTION: bool = true;           // camera or object motion between this frame and the last
override HAS_VERTEX_NORMALS: bool = true;   // any mesh with vertex normals (else shading = geometric normal)
override HAS_SURFACE_COLORS: bool = true;   // any mesh with vertex colours or a texture (else the materials')
override HAS_NORMAL_MAPS: bool = true;      // any mesh with a normal map
override WRITE_AOVS: bool = true;           // albedo, normal, depth and motion planes are wanted
