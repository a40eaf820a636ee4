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
@group(0) @binding(1) var<storage, read> lights: array<LightSample>;
@group(0) @binding(2) var<storage, read> views: array<ShadowView>;
@group(0) @binding(3) var maps: texture_depth_2d_array;
// Linear RGB albedo per draw, indexed by the draw's instance; w is 0, or
// 1 + k for a reflective object with cube map k (layers 6k to 6k + 5).
@group(0) @binding(4) var<storage, read> albedos: array<vec4<f32>>;

struct Eye {
    position: vec4<f32>,
    // first shadow view, view count.
    views: vec4<u32>,
}

// The other observers' eyes.
@group(0) @binding(5) var<storage, read> eyes: array<Eye>;

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

// As in irradiance_map.wgsl.
fn visible(p: vec3<f32>, n: vec3<f32>, origin: vec3<f32>, first: u32, count: u32) -> bool {
    if (count == 6u) {
        return visible_in_cube(p, n, origin, first);
    }
    for (var i = first; i < first + count; i++) {
        let v = views[i];
        let c = v.clip_from_world * vec4<f32>(p, 1.0);
        if (c.w <= 0.0) {
            continue;
        }
        let ndc = c.xy / c.w;
        if (abs(ndc.x) > 1.0 || abs(ndc.y) > 1.0) {
            continue;
        }
        return nearest_or_nearer(n, p - v.origin.xyz, ndc, i, v.origin.w);
    }
    return true;
}

// `visible` for six views that are a cube around `origin`
// (shadow_views::cube_views: +x, -x, +y, -y, +z, -z): only the face of
// the major axis can hold p, and its projection is an axis permutation,
// so no view needs to be read (shadow_views::cube_coords mirrors this).
fn visible_in_cube(p: vec3<f32>, n: vec3<f32>, origin: vec3<f32>, first: u32) -> bool {
    let d = p - origin;
    let a = abs(d);
    var face = 5u;
    // (right, up, forward) of d in the face's view (look_to_rh axes).
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
    if (c.z <= 0.0) {
        return true;
    }
    let ndc = c.xy / c.z;
    if (abs(ndc.x) > 1.0 || abs(ndc.y) > 1.0) {
        return true;
    }
    return nearest_or_nearer(n, d, ndc, first + face, 2.0 / f32(frame.counts.z));
}

// The distance from a view's origin to the surface whose depth `z` a
// layer holds at texel (tx, ty): the forward distance from the depth
// (glam perspective_rh, depth 0 to 1, near and far of frame.shadow),
// stretched along the ray through the texel's centre. `texel` is the
// view's texel angle at its centre (2 tan(half fov) / res). A cleared
// texel (z = 1) gives at least the far plane.
fn shadow_distance(z: f32, tx: u32, ty: u32, texel: f32) -> f32 {
    let near = frame.shadow.x;
    let far = frame.shadow.y;
    // 1 - z is exact for z >= 0.5, where the depth's precision matters.
    let forward = near / ((1.0 - z) + z * (near / far));
    let fres = f32(frame.counts.z);
    let tan_half = 0.5 * texel * fres;
    let c = vec2<f32>((f32(tx) + 0.5) / fres * 2.0 - 1.0, 1.0 - (f32(ty) + 0.5) / fres * 2.0);
    return forward * sqrt(1.0 + dot(c, c) * tan_half * tan_half);
}

// Compare the distance along `to` (from a view's origin to the point, of
// surface normal n) with the distance stored in layer `layer` at `ndc`;
// `texel` is the view's texel angle (radians) at its centre.
fn nearest_or_nearer(n: vec3<f32>, to: vec3<f32>, ndc: vec2<f32>, layer: u32, texel: f32) -> bool {
    let res = frame.counts.z;
    let fres = f32(res);
    let tx = min(u32((ndc.x * 0.5 + 0.5) * fres), res - 1u);
    let ty = min(u32((0.5 - ndc.y * 0.5) * fres), res - 1u);
    let stored = shadow_distance(textureLoad(maps, vec2<u32>(tx, ty), layer, 0), tx, ty, texel);
    let dist = length(to);
    // Slope-scaled bias: a texel spans dist * angle, stretched by the
    // receiver's tilt to the view.
    let cos_t = clamp(abs(dot(n, to)) / max(dist, 1e-20), 0.05, 1.0);
    let tan_t = sqrt(1.0 - cos_t * cos_t) / cos_t;
    let bias = dist * texel * (1.5 + 2.0 * tan_t) + 1e-4;
    return dist <= stored + bias;
}

// As in irradiance_map.wgsl.
fn intensity_towards(s: LightSample, dir: vec3<f32>) -> vec3<f32> {
    let kind = s.axis.w;
    var factor = 1.0;
    if (kind > 1.5) {
        factor = max(dot(s.axis.xyz, dir), 0.0);
    } else if (kind > 0.5) {
        let c = dot(s.axis.xyz, dir);
        let width = s.cone.x - s.cone.y;
        if (!(c > s.cone.y)) {
            factor = 0.0;
        } else if (width > 0.0) {
            let t = clamp((c - s.cone.y) / width, 0.0, 1.0);
            factor = t * t * (3.0 - 2.0 * t);
        }
    }
    return s.intensity.rgb * factor;
}

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
        if ((frame.counts.w & 1u) != 0u && !visible(p, n, s.position.xyz, s.views.x, s.views.y)) {
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
    for (var e = 0u; e < frame.counts.y; e++) {
        if (e == frame.own.x) {
            continue;
        }
        let eye = eyes[e];
        if (dot(n, eye.position.xyz - p) > 0.0 && !visible(p, n, eye.position.xyz, eye.views.x, eye.views.y)) {
            return vec4<f32>(shade(p, n, albedos[in.object].rgb), 1.0);
        }
    }
    return vec4<f32>(0.0, 0.0, 0.0, 0.0);
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
