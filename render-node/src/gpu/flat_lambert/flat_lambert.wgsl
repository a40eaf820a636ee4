// Flat Lambert pass: meshes seen from a pinhole device, one directional
// light, one colour per triangle. CPU reference: light::raster.

struct View {
    // PinholeDevice::clip_from_world (OpenCV device -> wgpu clip space).
    clip_from_world: mat4x4<f32>,
    // Unit direction towards the light, world space; w unused.
    to_light: vec4<f32>,
}

struct Object {
    world_from_object: mat4x4<f32>,
    // Inverse transpose of the linear part, in the upper 3x3.
    normal_from_object: mat4x4<f32>,
    // Linear RGB albedo; w unused.
    albedo: vec4<f32>,
}

@group(0) @binding(0) var<uniform> view: View;
@group(1) @binding(0) var<uniform> object: Object;

struct VertexIn {
    @location(0) position: vec3<f32>,
    // The unit geometric normal of the vertex's triangle, object space.
    @location(1) face_normal: vec3<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) colour: vec3<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    let world = object.world_from_object * vec4<f32>(v.position, 1.0);
    let n = (object.normal_from_object * vec4<f32>(v.face_normal, 0.0)).xyz;
    let len = length(n);
    // A degenerate triangle covers no pixel; keep its value finite anyway.
    let n_dot_l = select(0.0, dot(n, view.to_light.xyz) / len, len > 0.0);
    var out: VertexOut;
    out.clip = view.clip_from_world * world;
    out.colour = object.albedo.rgb * max(n_dot_l, 0.0);
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(in.colour, 1.0);
}
