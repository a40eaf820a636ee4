// Face view pass: one eye's view through a CRT face and its beam splitter
// (mirror_view::FaceView::clip_from_world). Real phantoms are drawn black
// with depth, so real objects hide virtual ones; virtual objects are shaded
// rho / pi * E with E from the virtual light samples (shadow types 2 and 3
// from the light shadow views, which hold phantoms and virtual objects)
// plus ambient. Occluding occlusion shadows: a phantom point inside the
// occlusion shadow of any other tracked eye (another observer's, or this
// observer's other eye; a virtual object between it and that eye, from
// the eye shadow views) is drawn as the lit real surface instead of black. Reflective virtual objects (albedo w > 0)
// show their cube map of the real environment, albedo * C(reflect(d, n)),
// C sampled bilinearly within a face (render::cube_map). The cube-map
// pass draws the phantoms into the maps with this module's vs_main and
// fs_environment (gpu::cube_map). CPU reference: render::face.

struct Frame {
    // FaceView::clip_from_world of this eye.
    clip_from_world: mat4x4<f32>,
    // xyz: the eye.
    eye: vec4<f32>,
    // rgb: ambient irradiance (W/m^2).
    ambient: vec4<f32>,
    // light samples, other eyes, shadow map size, flags (1: shadows,
    // 2: occluding occlusion shadows).
    counts: vec4<u32>,
    // near and far plane of the shadow views.
    shadow: vec4<f32>,
    // cube map texels per side.
    cube: vec4<u32>,
    // x: this eye's own entry in `eyes` (skipped), 0xffffffff for none.
    own: vec4<u32>,
}

struct LightSample {
    position: vec4<f32>,
    intensity: vec4<f32>,
    // xyz: spot axis or emitter normal; w: 0 isotropic, 1 spot, 2 cosine.
    axis: vec4<f32>,
    // cos inner, cos outer.
    cone: vec4<f32>,
    // first shadow view, view count.
    views: vec4<u32>,
}

struct ShadowView {
    clip_from_world: mat4x4<f32>,
    // xyz origin, w texel angle (radians).
    origin: vec4<f32>,
}

@group(0) @binding(0) var<uniform> frame: Frame;
// Per-frame arrays: uniform arrays of fixed capacity, or runtime-sized
// storage arrays when a frame exceeds one (gpu::frame_arrays). 256 views:
// the shadow maps' array layers are limited to 256 anyway.
@group(0) @binding(1) var<uniform> lights: array<LightSample, 64>;
@group(0) @binding(2) var<uniform> views: array<ShadowView, 256>;
@group(0) @binding(3) var maps: texture_depth_2d_array;
// Linear RGB albedo per draw, indexed by the draw's instance; w is 0, or
// 1 + k for a reflective object with cube map k (layers 6k to 6k + 5).
@group(0) @binding(4) var<uniform> albedos: array<vec4<f32>, 256>;

struct Eye {
    position: vec4<f32>,
    // first shadow view, view count.
    views: vec4<u32>,
}

// The other observers' eyes.
@group(0) @binding(5) var<uniform> eyes: array<Eye, 16>;

// The cube maps (faces as in shadow_views::cube_views, six layers each).
// Not bound in the cube-map pass, which draws them.
@group(0) @binding(6) var cube_maps: texture_2d_array<f32>;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) @interpolate(flat) normal: vec3<f32>,
    @location(2) @interpolate(flat) object: u32,
}

@vertex
fn vs_main(v: VertexIn, @builtin(instance_index) object: u32) -> VertexOut {
    var out: VertexOut;
    out.clip = frame.clip_from_world * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.object = object;
    return out;
}

// visible_from_light, visible_from_eye, intensity_towards:
// gpu/shadow_lookup.part.wgsl.

// rho / pi * E at p with unit normal n (the side facing the eye).
fn shade(p: vec3<f32>, n: vec3<f32>, rho: vec3<f32>) -> vec3<f32> {
    var e = max(frame.ambient.rgb, vec3<f32>(0.0));
    for (var i = 0u; i < frame.counts.x; i++) {
        let s = lights[i];
        let to_light = s.position.xyz - p;
        let r2 = dot(to_light, to_light);
        if (!(r2 > 0.0)) {
            continue;
        }
        let dir = to_light / sqrt(r2);
        let cos_t = dot(n, dir);
        if (!(cos_t > 0.0)) {
            continue;
        }
        if ((frame.counts.w & 1u) != 0u && !visible_from_light(p, n, s)) {
            continue;
        }
        e += intensity_towards(s, -dir) * (cos_t / r2);
    }
    return rho * e * 0.31830988618379067;
}

fn facing(in: VertexOut) -> vec3<f32> {
    var n = in.normal;
    if (dot(n, frame.eye.xyz - in.world) < 0.0) {
        n = -n;
    }
    return n;
}

@fragment
fn fs_phantom(in: VertexOut) -> @location(0) vec4<f32> {
    if ((frame.counts.w & 2u) == 0u) {
        return vec4<f32>(0.0, 0.0, 0.0, 0.0);
    }
    let p = in.world;
    let n = facing(in);
    // Shade once, after the loop: a return inside it would make llvmpipe
    // run `shade` (all light lookups) once per eye for every pixel, since
    // both sides of a branch that differs between pixels run for all.
    var occluded = false;
    for (var e = 0u; e < frame.counts.y; e++) {
        let eye = eyes[e];
        occluded = occluded || (e != frame.own.x && dot(n, eye.position.xyz - p) > 0.0 && !visible_from_eye(p, n, eye.position.xyz, eye.views.x, eye.views.y));
    }
    if (!occluded) {
        return vec4<f32>(0.0, 0.0, 0.0, 0.0);
    }
    return vec4<f32>(shade(p, n, albedos[in.object].rgb), 1.0);
}


// Radiance of cube map `k` along `d`: bilinear between the texel centres
// of d's face (cube_coords), clamped at the face's edges
// (render::cube_map::CubeMap::sample).
fn cube_sample(k: u32, d: vec3<f32>) -> vec3<f32> {
    let a = abs(d);
    var face = 5u;
    var c = vec3<f32>(d.x, d.y, -d.z);
    if (a.x >= a.y && a.x >= a.z) {
        face = select(1u, 0u, d.x > 0.0);
        c = select(vec3<f32>(-d.z, d.y, -d.x), vec3<f32>(d.z, d.y, d.x), d.x > 0.0);
    } else if (a.y >= a.z) {
        face = select(3u, 2u, d.y > 0.0);
        c = select(vec3<f32>(-d.x, d.z, -d.y), vec3<f32>(d.x, d.z, d.y), d.y > 0.0);
    } else if (d.z > 0.0) {
        face = 4u;
        c = vec3<f32>(-d.x, d.y, d.z);
    }
    if (!(c.z > 0.0)) {
        return vec3<f32>(0.0);
    }
    let res = f32(frame.cube.x);
    let ndc = c.xy / c.z;
    let f = vec2<f32>((ndc.x * 0.5 + 0.5) * res - 0.5, (0.5 - ndc.y * 0.5) * res - 0.5);
    let f0 = floor(f);
    let t = f - f0;
    let hi = vec2<f32>(res - 1.0);
    let p0 = vec2<u32>(clamp(f0, vec2<f32>(0.0), hi));
    let p1 = vec2<u32>(clamp(f0 + 1.0, vec2<f32>(0.0), hi));
    let layer = 6u * k + face;
    let c00 = textureLoad(cube_maps, p0, layer, 0).rgb;
    let c10 = textureLoad(cube_maps, vec2<u32>(p1.x, p0.y), layer, 0).rgb;
    let c01 = textureLoad(cube_maps, vec2<u32>(p0.x, p1.y), layer, 0).rgb;
    let c11 = textureLoad(cube_maps, p1, layer, 0).rgb;
    return mix(mix(c00, c10, t.x), mix(c01, c11, t.x), t.y);
}

@fragment
fn fs_virtual(in: VertexOut) -> @location(0) vec4<f32> {
    let a = albedos[in.object];
    if (a.w > 0.5) {
        let d = normalize(in.world - frame.eye.xyz);
        let r = reflect(d, facing(in));
        return vec4<f32>(a.rgb * cube_sample(u32(a.w - 0.5), r), 1.0);
    }
    return vec4<f32>(shade(in.world, facing(in), a.rgb), 1.0);
}

// The cube-map pass: a phantom's radiance rho / pi * E seen from the
// map's centre (frame.eye), virtual lights with shadows and ambient.
@fragment
fn fs_environment(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(shade(in.world, facing(in), albedos[in.object].rgb), 1.0);
}
