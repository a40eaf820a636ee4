// Shadow views: the distance from a view's origin to the nearest surface,
// one perspective view per layer of an R32Float array texture. Point light
// samples get six 90-degree cube faces; eyes one view fitted around the
// virtual objects. CPU reference: visibility rays in render::projector.

struct ShadowView {
    // Perspective view of this layer (glam perspective_rh * look_to_rh).
    clip_from_world: mat4x4<f32>,
    // xyz: the view's origin (light sample or eye); w: angular size of a
    // texel at the view's centre (radians), for the comparison bias.
    origin: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> views: array<ShadowView>;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) @interpolate(flat) view: u32,
}

@vertex
fn vs_main(v: VertexIn, @builtin(instance_index) view: u32) -> VertexOut {
    var out: VertexOut;
    out.clip = views[view].clip_from_world * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.view = view;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(distance(in.world, views[in.view].origin.xyz), 0.0, 0.0, 1.0);
}
