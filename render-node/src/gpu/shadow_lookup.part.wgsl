// Shadow-map lookups shared by the irradiance-map and face-view passes
// (gpu::shadow_lookup appends this file to each), and the per-frame
// records both read: the structs LightSample, Eye and ShadowView,
// cube_face, visible_from_light, visible_from_eye, intensity_towards. A
// shader that uses it declares `frame` (with counts.z the shadow map size
// and shadow.xy the views' near and far), `views` (an array of
// ShadowView) and `maps: texture_depth_2d_array`.

// A light sample (Rust: gpu::shadow_lookup::LightSampleGpu).
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

// A tracked eye whose occlusion shadows are looked up (Rust:
// gpu::shadow_lookup::EyeGpu).
struct Eye {
    // xyz position.
    position: vec4<f32>,
    // first shadow view, view count.
    views: vec4<u32>,
}

// One shadow view (Rust: gpu::shadow_views::ShadowView).
struct ShadowView {
    clip_from_world: mat4x4<f32>,
    // xyz origin, w texel angle (radians).
    origin: vec4<f32>,
}

// The cube face holding direction d and d's (right, up, forward) in that
// face's view (look_to_rh axes), as cube_face returns them.
struct CubeFace {
    face: u32,
    c: vec3<f32>,
}

// The face of six views that are a cube (shadow_views::cube_views: +x,
// -x, +y, -y, +z, -z) holding direction d: the face of its major axis,
// whose projection is an axis permutation, so no view needs to be read.
// Mirrors showcase_light::render::cube_map::world_to_face.
fn cube_face(d: vec3<f32>) -> CubeFace {
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
    return CubeFace(face, c);
}

// A surface point p (normal n) is visible from a view's origin when the
// views of that origin see nothing nearer to it than p along the line to
// p. A point no view covers is visible (eye views cover only the virtual
// objects).

// Visibility from a light sample: with shadows on, every sample has the six
// cube views (render::gpu_frame::light_inputs), so the cube lookup is taken
// directly. On llvmpipe both sides of a branch that differs between
// pixels, and every iteration of such a loop, run for all pixels, so
// straight code is what is cheap.
fn visible_from_light(p: vec3<f32>, n: vec3<f32>, s: LightSample) -> bool {
    return visible_in_cube(p, n, s.position.xyz, s.views.x);
}

// Visibility from an eye: its views are one view fitted around the virtual
// objects, or the six cube views when it is (nearly) inside them
// (shadow_views::fitted_views), or none; no loop (see above).
fn visible_from_eye(p: vec3<f32>, n: vec3<f32>, origin: vec3<f32>, first: u32, count: u32) -> bool {
    if (count == 6u) {
        return visible_in_cube(p, n, origin, first);
    }
    if (count != 1u) {
        return true;
    }
    let v = views[first];
    let c = v.clip_from_world * vec4<f32>(p, 1.0);
    let ndc = c.xy / c.w;
    if (c.w <= 0.0 || abs(ndc.x) > 1.0 || abs(ndc.y) > 1.0) {
        return true;
    }
    return nearest_or_nearer(n, p - v.origin.xyz, ndc, first, v.origin.w);
}

// Visibility through six views that are a cube around `origin`: only
// the face cube_face picks can hold p.
fn visible_in_cube(p: vec3<f32>, n: vec3<f32>, origin: vec3<f32>, first: u32) -> bool {
    let d = p - origin;
    let cube = cube_face(d);
    if (cube.c.z <= 0.0) {
        return true;
    }
    let ndc = cube.c.xy / cube.c.z;
    if (abs(ndc.x) > 1.0 || abs(ndc.y) > 1.0) {
        return true;
    }
    return nearest_or_nearer(n, d, ndc, first + cube.face, 2.0 / f32(frame.counts.z));
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
