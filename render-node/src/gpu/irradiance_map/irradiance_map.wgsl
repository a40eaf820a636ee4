// Irradiance map pass (paper sections 5.1, 5.2): the real phantoms seen
// from a projector; per pixel L = E / (cos(theta_p) / r^2) in W/sr, where E
// is the virtual lights' irradiance with shadow types 4 and 5 (distance
// maps of the shadow views) plus ambient; occlusion shadows of every eye;
// then device compensation. CPU reference: render::projector (the units
// and rules are documented there).

struct Frame {
    // PinholeDevice::clip_from_world of the projector.
    clip_from_world: mat4x4<f32>,
    // xyz: projector centre.
    projector: vec4<f32>,
    // rgb: ambient irradiance (W/m^2).
    ambient: vec4<f32>,
    // gamma, eta, black level, cos floor.
    response: vec4<f32>,
    // light samples, eyes, shadow map size, flags (1: shadows, 2: occlusion).
    counts: vec4<u32>,
    // near and far plane of the shadow views.
    shadow: vec4<f32>,
}

struct LightSample {
    // xyz position.
    position: vec4<f32>,
    // rgb peak radiant intensity (W/sr).
    intensity: vec4<f32>,
    // xyz: spot axis or emitter normal; w: 0 isotropic, 1 spot, 2 cosine.
    axis: vec4<f32>,
    // cos inner, cos outer.
    cone: vec4<f32>,
    // first shadow view, view count.
    views: vec4<u32>,
}

struct Eye {
    // xyz position.
    position: vec4<f32>,
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
@group(0) @binding(2) var<storage, read> eyes: array<Eye>;
@group(0) @binding(3) var<storage, read> views: array<ShadowView>;
@group(0) @binding(4) var maps: texture_depth_2d_array;
// Per projector pixel: its share of the target where other projectors
// overlap (render::blend; 1 without overlap).
@group(0) @binding(5) var blend: texture_2d<f32>;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) @interpolate(flat) normal: vec3<f32>,
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
    return out;
}

// True when the views `first .. first + count` (all from `origin`) see
// nothing nearer to their origin than `p` (surface normal `n`) along the
// line to `p`. A point no view covers is visible (eye views cover only
// the virtual objects).
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
            if (dot(n, eye.position.xyz - p) > 0.0 && !visible(p, n, eye.position.xyz, eye.views.x, eye.views.y)) {
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
            if ((flags & 1u) != 0u && !visible(p, n, s.position.xyz, s.views.x, s.views.y)) {
                continue;
            }
            e += intensity_towards(s, -dir) * (cos_t / r2l);
        }
        let share = textureLoad(blend, vec2<u32>(in.clip.xy), 0).r;
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
