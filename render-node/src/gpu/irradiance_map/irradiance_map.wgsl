// Irradiance map pass (paper sections 5.1, 5.2): the real phantoms seen
// from a projector; per pixel L = E / (cos(theta_p) / r^2) in W/sr, where E
// is the virtual lights' irradiance with shadow types 4 and 5 (distance
// maps of the shadow views) plus ambient; occlusion shadows of every eye;
// in global mode the correction field of render::indirect (flag 8), drawn
// as per-vertex values (gpu/irradiance_map/field.rs); then device
// compensation. CPU reference: render::projector (the units and rules are
// documented there).

struct Frame {
    // PinholeDevice::clip_from_world of the projector.
    clip_from_world: mat4x4<f32>,
    // xyz: projector centre.
    projector: vec4<f32>,
    // rgb: ambient irradiance (W/m^2).
    ambient: vec4<f32>,
    // gamma, eta, black level, cos floor.
    response: vec4<f32>,
    // light samples, eyes, shadow map size, flags (1: shadows, 2: occlusion,
    // 4: blend weights other than 1, 8: a global-illumination field).
    counts: vec4<u32>,
    // near and far plane of the shadow views.
    shadow: vec4<f32>,
}

@group(0) @binding(0) var<uniform> frame: Frame;
// Per-frame arrays: uniform arrays of fixed capacity, or runtime-sized
// storage arrays when a frame exceeds one (gpu::frame_arrays). 256 views:
// the shadow maps' array layers are limited to 256 anyway.
@group(0) @binding(1) var<uniform> lights: array<LightSample, 64>;
@group(0) @binding(2) var<uniform> eyes: array<Eye, 16>;
@group(0) @binding(3) var<uniform> views: array<ShadowView, 256>;
@group(0) @binding(4) var maps: texture_depth_2d_array;
// Per projector pixel: its share of the target where other projectors
// overlap (render::blend; 1 without overlap).
@group(0) @binding(5) var blend: texture_2d<f32>;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    // The global-illumination field at the vertex (W/m^2; 0 in direct
    // mode).
    @location(2) field: vec3<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) @interpolate(flat) normal: vec3<f32>,
    @location(2) field: vec3<f32>,
}

struct FragmentOut {
    // rgb: L (W/sr); a: 1 unclipped, 2 clipped, 3 masked (0: no surface).
    @location(0) irradiance: vec4<f32>,
    // rgb: compensated pixel value; a: 1.
    @location(1) value: vec4<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = frame.clip_from_world * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.field = v.field;
    return out;
}

// LightSample, Eye, ShadowView, visible_from_light, visible_from_eye,
// intensity_towards: gpu/shadow_lookup.part.wgsl.

@fragment
fn fs_main(in: VertexOut) -> FragmentOut {
    var out: FragmentOut;
    let p = in.world;
    let to_projector = frame.projector.xyz - p;
    let r2 = dot(to_projector, to_projector);
    let dir_p = to_projector / sqrt(r2);
    var n = in.normal;
    if (dot(n, dir_p) < 0.0) {
        n = -n;
    }
    let cos_p = dot(n, dir_p);
    if (!(cos_p >= frame.response.w) || !(r2 > 0.0)) {
        out.irradiance = vec4<f32>(0.0, 0.0, 0.0, 3.0);
        out.value = vec4<f32>(0.0, 0.0, 0.0, 1.0);
        return out;
    }
    let flags = frame.counts.w;
    var occluded = false;
    if ((flags & 2u) != 0u) {
        for (var e = 0u; e < frame.counts.y; e++) {
            let eye = eyes[e];
            if (dot(n, eye.position.xyz - p) > 0.0 && !visible_from_eye(p, n, eye.position.xyz, eye.views.x, eye.views.y)) {
                occluded = true;
                break;
            }
        }
    }
    var l = vec3<f32>(0.0);
    if (!occluded) {
        var e = max(frame.ambient.rgb, vec3<f32>(0.0));
        for (var i = 0u; i < frame.counts.x; i++) {
            let s = lights[i];
            let to_light = s.position.xyz - p;
            let r2l = dot(to_light, to_light);
            if (!(r2l > 0.0)) {
                continue;
            }
            let dir = to_light / sqrt(r2l);
            let cos_t = dot(n, dir);
            if (!(cos_t > 0.0)) {
                continue;
            }
            if ((flags & 1u) != 0u && !visible_from_light(p, n, s)) {
                continue;
            }
            e += intensity_towards(s, -dir) * (cos_t / r2l);
        }
        if ((flags & 8u) != 0u) {
            e += in.field;
        }
        // The same for every pixel of a frame, so llvmpipe skips the
        // fetch when no other projector overlaps (share 1 exactly).
        var share = 1.0;
        if ((flags & 4u) != 0u) {
            share = textureLoad(blend, vec2<u32>(in.clip.xy), 0).r;
        }
        l = e * (share * r2 / cos_p);
    }
    // Device compensation: v = ((L - black) / eta)^(1 / gamma), clamped.
    let gamma = frame.response.x;
    let eta = frame.response.y;
    let black = frame.response.z;
    let linear = (l - vec3<f32>(black)) / eta;
    let slack = 1e-6 * (1.0 + black / eta);
    let clipped = any(linear < vec3<f32>(-slack)) || any(linear > vec3<f32>(1.0 + slack));
    let c = clamp(linear, vec3<f32>(0.0), vec3<f32>(1.0));
    let v = select(pow(c, vec3<f32>(1.0 / gamma)), vec3<f32>(0.0), c <= vec3<f32>(0.0));
    out.irradiance = vec4<f32>(l, select(1.0, 2.0, clipped));
    out.value = vec4<f32>(v, 1.0);
    return out;
}
