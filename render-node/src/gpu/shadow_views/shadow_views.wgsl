// Shadow views: the depth of the nearest surface in one perspective view
// per layer of a depth array texture (no fragment stage). Point light
// samples get six 90-degree cube faces; eyes one view fitted around the
// virtual objects. The sampling passes turn depth back into distance from
// the view's origin (shadow_distance in irradiance_map.wgsl). CPU
// reference: visibility rays in render::projector.

struct ShadowView {
    // Perspective view of this layer (glam perspective_rh * look_to_rh).
    clip_from_world: mat4x4<f32>,
    // xyz: the view's origin (light sample or eye); w: size of a texel at
    // the view's centre (radians), for the comparison bias.
    origin: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> views: array<ShadowView>;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
}

@vertex
fn vs_main(v: VertexIn, @builtin(instance_index) view: u32) -> @builtin(position) vec4<f32> {
    return views[view].clip_from_world * vec4<f32>(v.position, 1.0);
}
