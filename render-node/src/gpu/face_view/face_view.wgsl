// Face view pass: one eye's view through a CRT face and its beam splitter
// (mirror_view::FaceView::clip_from_world). Real phantoms are drawn black
// with depth, so real objects hide virtual ones; virtual objects are shaded
// rho / pi * E with E from the virtual light samples (shadow types 2 and 3
// from the light shadow views, which hold phantoms and virtual objects)
// plus ambient. Occluding occlusion shadows: a phantom point inside the
// occlusion shadow of any other tracked eye (another observer's, or this
// observer's other eye; a virtual object between it and that eye, from
// the eye shadow views) is drawn as the lit real surface instead of black.
// Reflective virtual objects (albedo w > 0) show their cube map of the
// real environment, albedo * C(p, reflect(d, n)), C the distance-corrected
// lookup (the maps hold each texel's distance in alpha) sampled
// bilinearly within a face (render::cube_map). The cube-map pass draws
// the phantoms into the maps with this module's vs_main and
// fs_environment (gpu::cube_map). Global mode adds the field to E, and
// draws each virtual object less the real surface's own interreflection
// that the eye sees through it (fs_seen_through, a pass of its own
// before this one). CPU reference: render::face.

struct Frame {
    // FaceView::clip_from_world of this eye.
    clip_from_world: mat4x4<f32>,
    // xyz: the eye.
    eye: vec4<f32>,
    // rgb: ambient irradiance (W/m^2).
    ambient: vec4<f32>,
    // light samples, other eyes, shadow map size, flags (1: shadows,
    // 2: occluding occlusion shadows, 4: global mode's seen-through image).
    counts: vec4<u32>,
    // near and far plane of the shadow views.
    shadow: vec4<f32>,
    // cube map texels per side, cube maps, the entry of `albedos` holding
    // map 0's centre (map k's at that + k).
    cube: vec4<u32>,
    // x: this eye's own entry in `eyes` (skipped), 0xffffffff for none.
    own: vec4<u32>,
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
// After the draws: xyz of each cube map's centre (frame.cube.z on).
@group(0) @binding(4) var<uniform> albedos: array<vec4<f32>, 256>;

// The other observers' eyes.
@group(0) @binding(5) var<uniform> eyes: array<Eye, 16>;

// The cube maps (faces as in shadow_views::cube_views, six layers each).
// Not bound in the cube-map pass, which draws them.
@group(0) @binding(6) var cube_maps: texture_2d_array<f32>;

// What this eye sees of the real surfaces' own interreflection at each
// pixel (fs_seen_through; zero in direct mode): the observer sees it
// through the virtual objects, so they are drawn less it. Not bound in
// the passes that draw it or the cube maps.
@group(0) @binding(7) var seen_through: texture_2d<f32>;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) @interpolate(flat) normal: vec3<f32>,
    @location(2) @interpolate(flat) object: u32,
    // The global-illumination field (W/m^2): what the displays add to E,
    // and the real surfaces' own interreflection (IndirectLight).
    @location(3) field: vec3<f32>,
    @location(4) cabinet: vec3<f32>,
}

// Every pass's vertices, with the global-illumination field per vertex
// (gpu::field; zeros in direct mode), interpolated linearly inside each
// piece as IndirectField::at does.
@vertex
fn vs_main(
    v: VertexIn,
    @location(2) field: vec3<f32>,
    @location(3) cabinet: vec3<f32>,
    @builtin(instance_index) object: u32,
) -> VertexOut {
    var out: VertexOut;
    out.clip = frame.clip_from_world * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.object = object;
    out.field = field;
    out.cabinet = cabinet;
    return out;
}

// LightSample, Eye, ShadowView, cube_face, visible_from_light,
// visible_from_eye, intensity_towards: gpu/shadow_lookup.part.wgsl.

// rho / pi * E at p with unit normal n (the side facing the eye), E the
// virtual lights' direct irradiance, the ambient and `field`.
fn shade(p: vec3<f32>, n: vec3<f32>, rho: vec3<f32>, field: vec3<f32>) -> vec3<f32> {
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
    return rho * (e + field) * 0.31830988618379067;
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
    return vec4<f32>(shade(p, n, albedos[in.object].rgb, in.field), 1.0);
}


// Distance a cube texel holds where it meets no real surface, and the
// step counts of the distance-corrected lookup: render::cube_map's
// NO_SURFACE_DISTANCE, PARALLAX_LINEAR_STEPS, PARALLAX_SECANT_STEPS and
// PARALLAX_SURFACE_TOLERANCE.
const NO_SURFACE_DISTANCE: f32 = 1.0e6;
const PARALLAX_LINEAR_STEPS: u32 = 8u;
const PARALLAX_SECANT_STEPS: u32 = 4u;
const PARALLAX_SURFACE_TOLERANCE: f32 = 0.05;

// The four texels of cube map `k` a bilinear lookup along `d` reads
// (d's face, cube_face; clamped at the face's edges) and the weights.
struct CubeTexels {
    layer: u32,
    p0: vec2<u32>,
    p1: vec2<u32>,
    t: vec2<f32>,
    valid: bool,
}

fn cube_texels(k: u32, d: vec3<f32>) -> CubeTexels {
    let cube = cube_face(d);
    var out: CubeTexels;
    out.valid = cube.c.z > 0.0;
    let res = f32(frame.cube.x);
    let ndc = select(vec2<f32>(0.0), cube.c.xy / cube.c.z, out.valid);
    let f = vec2<f32>((ndc.x * 0.5 + 0.5) * res - 0.5, (0.5 - ndc.y * 0.5) * res - 0.5);
    let f0 = floor(f);
    out.t = f - f0;
    let hi = vec2<f32>(res - 1.0);
    out.p0 = vec2<u32>(clamp(f0, vec2<f32>(0.0), hi));
    out.p1 = vec2<u32>(clamp(f0 + 1.0, vec2<f32>(0.0), hi));
    out.layer = 6u * k + cube.face;
    return out;
}

// Radiance (rgb) and distance (a) of cube map `k` along `d`: bilinear
// between the texel centres of d's face, clamped at the face's edges
// (render::cube_map::CubeMap::sample and distance_along).
fn cube_bilinear(k: u32, d: vec3<f32>) -> vec4<f32> {
    let b = cube_texels(k, d);
    let c00 = textureLoad(cube_maps, b.p0, b.layer, 0);
    let c10 = textureLoad(cube_maps, vec2<u32>(b.p1.x, b.p0.y), b.layer, 0);
    let c01 = textureLoad(cube_maps, vec2<u32>(b.p0.x, b.p1.y), b.layer, 0);
    let c11 = textureLoad(cube_maps, b.p1, b.layer, 0);
    let v = mix(mix(c00, c10, b.t.x), mix(c01, c11, b.t.x), b.t.y);
    return select(vec4<f32>(0.0, 0.0, 0.0, NO_SURFACE_DISTANCE), v, b.valid);
}

fn cube_distance(k: u32, d: vec3<f32>) -> f32 {
    let v = cube_bilinear(k, d).a;
    return select(NO_SURFACE_DISTANCE, v, v > 0.0 && v < 3.0e38);
}

// |x - c| over the stored distance along x - c, x - c = o + t r.
fn cube_ratio(k: u32, o: vec3<f32>, r: vec3<f32>, t: f32) -> f32 {
    let x = o + t * r;
    return length(x) / cube_distance(k, x);
}

fn cube_secant(t_under: f32, q_under: f32, t_over: f32, q_over: f32) -> f32 {
    let w = (1.0 - q_under) / (q_over - q_under);
    let finite = abs(w) < 3.0e38;
    return t_under + (t_over - t_under) * select(0.0, clamp(w, 0.0, 1.0), finite);
}

// The direction from the centre of cube map `k` along which a mirror at
// `p` reflecting along unit `r` sees the stored environment: the point
// x = p + t r at the stored distance, by a linear search over t = s a /
// (1 - a), a = i / (steps + 1), s the stored distance along r (or along
// the bisector of p - c and r where nearer), then
// secant steps; r where no surface is found, 0 where the search ends on a
// silhouette (render::cube_map::CubeMap::reflection_direction). Fixed step counts
// and selects: no branch differs between pixels.
fn cube_reflection_direction(k: u32, p: vec3<f32>, r: vec3<f32>) -> vec3<f32> {
    let o = p - albedos[frame.cube.z + k].xyz;
    // The stored distance along r, or along the bisector of o and r where
    // that is nearer.
    let o_len = length(o);
    let o_dir = select(vec3<f32>(0.0), o / o_len, o_len > 0.0);
    let scale = min(cube_distance(k, r), cube_distance(k, o_dir + r));
    var t_under = 0.0;
    var q_under = cube_ratio(k, o, r, 0.0);
    var t_over = 0.0;
    var q_over = 0.0;
    var found = false;
    let steps = f32(PARALLAX_LINEAR_STEPS + 1u);
    for (var i = 1u; i <= PARALLAX_LINEAR_STEPS; i++) {
        let a = f32(i) / steps;
        let t = scale * a / (1.0 - a);
        let q = cube_ratio(k, o, r, t);
        let over = !found && q >= 1.0;
        t_over = select(t_over, t, over);
        q_over = select(q_over, q, over);
        let under = !found && !over;
        t_under = select(t_under, t, under);
        q_under = select(q_under, q, under);
        found = found || over;
    }
    for (var j = 0u; j < PARALLAX_SECANT_STEPS; j++) {
        let t = cube_secant(t_under, q_under, t_over, q_over);
        let q = cube_ratio(k, o, r, t);
        let under = q < 1.0;
        t_under = select(t_under, t, under);
        q_under = select(q_under, q, under);
        t_over = select(t, t_over, under);
        q_over = select(q, q_over, under);
    }
    let x = o + cube_secant(t_under, q_under, t_over, q_over) * r;
    let usable = found && all(abs(x) < vec3<f32>(3.0e38)) && any(x != vec3<f32>(0.0));
    // Ending on a jump of the stored distance (a silhouette seen from the
    // centre) instead of a surface: nothing real is seen (0, an invalid
    // direction for cube_bilinear).
    let on_surface = abs(length(x) / cube_distance(k, x) - 1.0) <= PARALLAX_SURFACE_TOLERANCE;
    return select(r, select(vec3<f32>(0.0), x, on_surface), usable);
}

// A virtual object's radiance `l` as the CRT shows it: less what the
// eye sees of the real surface behind it (render::face's
// real_seen_through), never below black.
fn less_seen_through(in: VertexOut, l: vec3<f32>) -> vec4<f32> {
    // Direct mode: nothing is seen through (no texel fetch per pixel).
    if ((frame.counts.w & 4u) == 0u) {
        return vec4<f32>(l, 1.0);
    }
    let behind = textureLoad(seen_through, vec2<u32>(in.clip.xy), 0).rgb;
    return vec4<f32>(max(l - behind, vec3<f32>(0.0)), 1.0);
}

// A diffuse virtual object, shaded by the virtual lights. Mirrors have
// their own entry point, chosen per draw: llvmpipe would run the
// reflection lookup for every pixel of a branch on the albedo's w.
@fragment
fn fs_virtual(in: VertexOut) -> @location(0) vec4<f32> {
    let a = albedos[in.object];
    return less_seen_through(in, shade(in.world, facing(in), a.rgb, in.field));
}

// A reflective virtual object: its albedo times its cube map (w: 1 + the
// map's index) along the distance-corrected reflected ray.
@fragment
fn fs_virtual_mirror(in: VertexOut) -> @location(0) vec4<f32> {
    let a = albedos[in.object];
    let d = normalize(in.world - frame.eye.xyz);
    let k = u32(max(a.w - 0.5, 0.0));
    let r = cube_reflection_direction(k, in.world, reflect(d, facing(in)));
    return less_seen_through(in, a.rgb * cube_bilinear(k, r).rgb);
}

// The seen-through pass (global mode): a phantom's own interreflected
// radiance, rho / pi * cabinet, the nearest phantom winning.
@fragment
fn fs_seen_through(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(albedos[in.object].rgb * in.cabinet * 0.31830988618379067, 1.0);
}

// The cube-map pass: a phantom's radiance rho / pi * E seen from the
// map's centre (frame.eye), virtual lights with shadows and ambient, in
// global mode with all its indirect light (what the projectors add and
// the real surfaces' own interreflection), and its distance from the
// centre in alpha (the clear value is NO_SURFACE_DISTANCE).
@fragment
fn fs_environment(in: VertexOut) -> @location(0) vec4<f32> {
    let n = facing(in);
    let e = in.field + in.cabinet;
    return vec4<f32>(shade(in.world, n, albedos[in.object].rgb, e), length(in.world - frame.eye.xyz));
}
