// GPU hemi-cube item buffer: every element triangle drawn with its id
// into one face of a hemi-cube. CPU reference: radiosity::hemicube
// (HemiCube::item_buffer, one ray per pixel centre).
//
// Depth is reversed (near / distance, compare Greater, cleared to 0), so
// that Depth32Float keeps its precision at every distance.

struct Face {
    // Clip space of this face from world space (its viewport is set by
    // the pass): x across the face, y down the face's rows, z = near,
    // w = distance along the face's axis.
    clip_from_world: mat4x4<f32>,
    // The hemi-cube's eye point, world space; w unused.
    origin: vec4<f32>,
}

@group(0) @binding(0) var<uniform> face: Face;

struct VertexIn {
    @location(0) position: vec3<f32>,
    // Item id + 1 (0 is "no item", the clear value).
    @location(1) item: u32,
    // Unit front normal of the vertex's triangle, world space.
    @location(2) normal: vec3<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) item: u32,
    // Positive when the eye is on the front side of the triangle's plane.
    @location(1) @interpolate(flat) facing: f32,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = face.clip_from_world * vec4<f32>(v.position, 1.0);
    out.item = v.item;
    out.facing = dot(v.normal, face.origin.xyz - v.position);
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) u32 {
    // A back face occludes (it writes depth) but is no item.
    return select(0u, in.item, in.facing > 0.0);
}
