//! CPU reference rasteriser: the same triangles, depth test and pixel-centre rules as the GPU, for pixel-wise comparison.
//!
//! It draws a [`FlatLambertScene`] exactly as `showcase_render::gpu::flat_lambert`
//! does, in f64:
//! - world to clip space by [`showcase_proto::PinholeDevice::clip_from_world`] (the one
//!   documented OpenCV to wgpu mapping), clipping against the near and far
//!   planes in homogeneous space;
//! - back faces culled: a front face winds counter-clockwise in NDC
//!   (y up), which is counter-clockwise as seen by the device for a mesh
//!   wound counter-clockwise about its outward normal;
//! - coverage sampled at pixel centres `(x + 0.5, y + 0.5)` with the
//!   top-left fill rule, so that triangles sharing an edge cover each pixel
//!   once;
//! - depth `z_ndc` in `0..1`, interpolated linearly in screen space, test
//!   `Less`, cleared to 1;
//! - flat Lambert shading per triangle: `albedo * max(0, n . l)` with the
//!   triangle's world-space geometric normal `n` and the unit direction `l`
//!   towards a directional light. Alpha is 1 where a triangle is drawn, 0
//!   where the clear colour `[0, 0, 0, 0]` remains.
//!
//! A GPU snaps vertices to a fixed-point sub-pixel grid (8 bits on most
//! hardware and on lavapipe) and computes in f32, so a pixel centre that
//! lies within a tiny distance of an edge, or whose two nearest surfaces
//! are nearly at the same depth, may legitimately resolve differently.
//! [`RasterImage::uncertain`] marks exactly those pixels, so that a
//! comparison can demand exact agreement everywhere else.

use glam::{DVec2, DVec4};

mod scene;

pub use scene::{DrawItem, FlatLambertScene, SceneError, face_normal, lambert, normal_from_object};

/// A pixel centre closer than this (in pixels) to an edge of a drawn
/// triangle is [`RasterImage::uncertain`]: eight times the worst vertex
/// snapping error of an 8-bit sub-pixel rasteriser.
pub const EDGE_TOLERANCE_PX: f64 = 1.0 / 64.0;

/// Two surfaces whose device depths `z` at a pixel centre differ by less
/// than this fraction of `z` make the pixel [`RasterImage::uncertain`].
pub const DEPTH_TOLERANCE_REL: f64 = 1e-5;

/// A CPU-rendered image of a [`FlatLambertScene`], row-major from the
/// top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct RasterImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB plus coverage alpha (1 drawn, 0 background).
    pub colour: Vec<[f32; 4]>,
    /// Device depth in `0..1`, 1 where nothing was drawn.
    pub depth: Vec<f32>,
    /// Pixels whose result hinges on a tie within [`EDGE_TOLERANCE_PX`] of
    /// an edge or [`DEPTH_TOLERANCE_REL`] in depth; a correct GPU may
    /// differ from this reference there, and only there.
    pub uncertain: Vec<bool>,
}

/// A vertex after projection: framebuffer position (pixels, y down) and
/// device depth `z_ndc`.
#[derive(Clone, Copy, Debug)]
struct ScreenVertex {
    p: DVec2,
    z: f64,
}

/// Per-pixel state while drawing.
struct Frame {
    width: usize,
    height: usize,
    colour: Vec<[f32; 4]>,
    depth: Vec<f64>,
    /// Nearest depth of any fragment that did not win the pixel, or that
    /// lies in an edge band; +inf if none.
    contender: Vec<f64>,
}

/// Rasterise `scene` on the CPU. See the module documentation for the
/// exact rules.
pub fn rasterise_flat_lambert(scene: &FlatLambertScene<'_>) -> Result<RasterImage, SceneError> {
    scene.validate()?;
    let device = scene.device;
    let (w, h) = (device.width as usize, device.height as usize);
    let mut frame = Frame {
        width: w,
        height: h,
        colour: vec![[0.0; 4]; w * h],
        depth: vec![1.0; w * h],
        contender: vec![f64::INFINITY; w * h],
    };
    let clip_from_world = device.clip_from_world();
    let to_light = scene.light_direction();
    for item in scene.items {
        let clip_from_object = clip_from_world * item.transform.matrix().as_dmat4();
        let normals = normal_from_object(&item.transform);
        for &tri in &item.mesh.triangles {
            let shade = lambert(&normals, face_normal(item.mesh, tri), to_light) as f32;
            let rgb = item.albedo * shade;
            let colour = [rgb.x, rgb.y, rgb.z, 1.0];
            let clip = tri
                .map(|i| clip_from_object * item.mesh.positions[i as usize].as_dvec3().extend(1.0));
            let polygon = clip_near_far(&clip);
            if polygon.len() < 3 {
                continue;
            }
            let screen: Vec<ScreenVertex> = polygon
                .iter()
                .map(|c| to_screen(*c, w as f64, h as f64))
                .collect();
            for i in 1..screen.len() - 1 {
                draw_triangle(&mut frame, [screen[0], screen[i], screen[i + 1]], colour);
            }
        }
    }
    let (n, f) = (device.near, device.far);
    let linear = |z_ndc: f64| f * n / (f - z_ndc * (f - n));
    let uncertain = frame
        .colour
        .iter()
        .zip(&frame.depth)
        .zip(&frame.contender)
        .map(|((c, &z), &other)| {
            if other == f64::INFINITY {
                false
            } else if c[3] == 0.0 {
                true
            } else {
                let z_win = linear(z);
                linear(other) <= z_win * (1.0 + DEPTH_TOLERANCE_REL)
            }
        })
        .collect();
    Ok(RasterImage {
        width: device.width,
        height: device.height,
        colour: frame.colour,
        depth: frame.depth.iter().map(|&d| d as f32).collect(),
        uncertain,
    })
}

/// Clip a triangle in homogeneous clip space against `0 <= z <= w`
/// (Sutherland-Hodgman); the result is a convex polygon, possibly empty.
fn clip_near_far(tri: &[DVec4; 3]) -> Vec<DVec4> {
    let near = |v: DVec4| v.z;
    let far = |v: DVec4| v.w - v.z;
    let mut poly = tri.to_vec();
    for plane in [&near as &dyn Fn(DVec4) -> f64, &far] {
        let mut out = Vec::with_capacity(poly.len() + 1);
        for (i, &a) in poly.iter().enumerate() {
            let b = poly[(i + 1) % poly.len()];
            let (da, db) = (plane(a), plane(b));
            if da >= 0.0 {
                out.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                out.push(a + (b - a) * (da / (da - db)));
            }
        }
        poly = out;
        if poly.is_empty() {
            break;
        }
    }
    poly
}

/// Perspective divide and viewport transform (y down, origin top-left).
fn to_screen(c: DVec4, width: f64, height: f64) -> ScreenVertex {
    let inv_w = 1.0 / c.w;
    ScreenVertex {
        p: DVec2::new(
            (c.x * inv_w + 1.0) * 0.5 * width,
            (1.0 - c.y * inv_w) * 0.5 * height,
        ),
        z: (c.z * inv_w).clamp(0.0, 1.0),
    }
}

/// 2D cross product `a x b`.
fn cross(a: DVec2, b: DVec2) -> f64 {
    a.x * b.y - a.y * b.x
}

/// Draw one screen-space triangle. Front faces have a negative signed
/// area in framebuffer coordinates (y down); back faces are culled, except
/// that a sliver thinner than the edge tolerance marks its pixels
/// uncertain whichever way it faces, since rounding can flip its facing.
fn draw_triangle(frame: &mut Frame, v: [ScreenVertex; 3], colour: [f32; 4]) {
    let area = cross(v[1].p - v[0].p, v[2].p - v[0].p);
    let longest = (0..3)
        .map(|i| (v[(i + 1) % 3].p - v[i].p).length())
        .fold(0.0, f64::max);
    let sliver = area.abs() <= 2.0 * EDGE_TOLERANCE_PX * longest;
    let front = area < 0.0;
    if !front && !sliver {
        return;
    }
    // Reorder to a positive signed area so that "inside" is E >= 0.
    let v = if area < 0.0 { [v[0], v[2], v[1]] } else { v };
    let area = area.abs();
    let eps = EDGE_TOLERANCE_PX;
    let lo = v.iter().fold(DVec2::INFINITY, |m, s| m.min(s.p)) - eps;
    let hi = v.iter().fold(DVec2::NEG_INFINITY, |m, s| m.max(s.p)) + eps;
    // Pixel x covers centre x + 0.5: the first centre >= lo is ceil(lo - 0.5).
    let x0 = (lo.x - 0.5).ceil().max(0.0);
    let y0 = (lo.y - 0.5).ceil().max(0.0);
    let x1 = (hi.x - 0.5).floor().min(frame.width as f64 - 1.0);
    let y1 = (hi.y - 0.5).floor().min(frame.height as f64 - 1.0);
    if x0 > x1 || y0 > y1 {
        return;
    }
    let edges: [(DVec2, DVec2, f64, bool); 3] = std::array::from_fn(|i| {
        let a = v[(i + 1) % 3].p;
        let d = v[(i + 2) % 3].p - a;
        // Top-left rule (y down): a left edge has the interior to its
        // right (d.y < 0), a top edge is horizontal with the interior
        // below it (d.y == 0, d.x > 0).
        let top_left = d.y < 0.0 || (d.y == 0.0 && d.x > 0.0);
        (a, d, d.length(), top_left)
    });
    for y in y0 as usize..=y1 as usize {
        for x in x0 as usize..=x1 as usize {
            let p = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
            // e[i] is twice the area of the sub-triangle opposite vertex i.
            let e: [f64; 3] = std::array::from_fn(|i| cross(edges[i].1, p - edges[i].0));
            let inside = front && (0..3).all(|i| e[i] > 0.0 || (e[i] == 0.0 && edges[i].3));
            let min_dist = (0..3)
                .map(|i| e[i] / edges[i].2.max(f64::MIN_POSITIVE))
                .fold(f64::INFINITY, f64::min);
            let in_band = (-eps..eps).contains(&min_dist);
            if !inside && !in_band {
                continue;
            }
            let z = if area > 0.0 {
                ((e[0] * v[0].z + e[1] * v[1].z + e[2] * v[2].z) / area).clamp(0.0, 1.0)
            } else {
                v[0].z
            };
            let idx = y * frame.width + x;
            if in_band {
                frame.contender[idx] = frame.contender[idx].min(z);
            }
            if inside {
                if z < frame.depth[idx] {
                    if frame.colour[idx][3] != 0.0 {
                        frame.contender[idx] = frame.contender[idx].min(frame.depth[idx]);
                    }
                    frame.depth[idx] = z;
                    frame.colour[idx] = colour;
                } else {
                    frame.contender[idx] = frame.contender[idx].min(z);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat3, DVec3, Quat, Vec3};
    use showcase_proto::{Mesh, PinholeDevice, Transform};

    /// A device looking down +z from the origin with focal length `f`,
    /// principal point at the centre: world (x, y) at depth z lands on
    /// pixel (cx + f x / z, cy + f y / z).
    fn straight_device(width: u32, height: u32, f: f64) -> PinholeDevice {
        PinholeDevice {
            width,
            height,
            k: DMat3::from_cols(
                DVec3::new(f, 0.0, 0.0),
                DVec3::new(0.0, f, 0.0),
                DVec3::new(0.5 * width as f64, 0.5 * height as f64, 1.0),
            ),
            rotation: DMat3::IDENTITY,
            translation: DVec3::ZERO,
            dist_coeffs: [0.0; 5],
            near: 0.1,
            far: 10.0,
        }
    }

    /// A quad at depth z covering the pixel rectangle [x0, x1] x [y0, y1]
    /// of `straight_device(.., f)`, wound to face the device.
    fn pixel_rect(dev: &PinholeDevice, r: [f64; 4], z: f64) -> Mesh {
        let (f, cx, cy) = (dev.k.x_axis.x, dev.k.z_axis.x, dev.k.z_axis.y);
        let w = |u: f64, v: f64| {
            Vec3::new(
                ((u - cx) * z / f) as f32,
                ((v - cy) * z / f) as f32,
                z as f32,
            )
        };
        let [x0, y0, x1, y1] = r;
        Mesh {
            positions: vec![w(x0, y0), w(x1, y0), w(x1, y1), w(x0, y1)],
            // Facing the device means -z, i.e. (b - a) x (c - a) along -z.
            triangles: vec![[0, 2, 1], [0, 3, 2]],
            ..Mesh::default()
        }
    }

    fn draw(dev: &PinholeDevice, meshes: &[(&Mesh, Vec3)]) -> RasterImage {
        let items: Vec<DrawItem<'_>> = meshes
            .iter()
            .map(|(m, a)| DrawItem {
                mesh: m,
                transform: Transform::IDENTITY,
                albedo: *a,
            })
            .collect();
        let scene = FlatLambertScene {
            device: dev,
            items: &items,
            to_light: Vec3::new(0.0, 0.0, -1.0),
        };
        rasterise_flat_lambert(&scene).expect("valid scene")
    }

    fn covered(img: &RasterImage) -> Vec<(u32, u32)> {
        (0..img.height)
            .flat_map(|y| (0..img.width).map(move |x| (x, y)))
            .filter(|&(x, y)| img.colour[(y * img.width + x) as usize][3] == 1.0)
            .collect()
    }

    #[test]
    fn rect_on_pixel_centres_follows_top_left_rule() {
        // Edges through the centres x = 0.5 and 2.5, y = 0.5 and 2.5: the
        // left and top edges own their centres, the right and bottom not.
        let dev = straight_device(4, 4, 4.0);
        let quad = pixel_rect(&dev, [0.5, 0.5, 2.5, 2.5], 1.0);
        let img = draw(&dev, &[(&quad, Vec3::ONE)]);
        assert_eq!(covered(&img), vec![(0, 0), (1, 0), (0, 1), (1, 1)]);
    }

    #[test]
    fn shared_diagonal_covers_each_centre_once() {
        // The quad's diagonal passes exactly through the centres (0.5, 0.5)
        // and (1.5, 1.5); together its two triangles cover all 9 centres
        // of [0, 3]^2 and each exactly once (no gap, no double hit).
        let dev = straight_device(3, 3, 3.0);
        let quad = pixel_rect(&dev, [0.0, 0.0, 3.0, 3.0], 1.0);
        for tri in &quad.triangles {
            let one = Mesh {
                triangles: vec![*tri],
                ..quad.clone()
            };
            assert!(!covered(&draw(&dev, &[(&one, Vec3::ONE)])).is_empty());
        }
        let halves: Vec<Vec<(u32, u32)>> = quad
            .triangles
            .iter()
            .map(|t| {
                let one = Mesh {
                    triangles: vec![*t],
                    ..quad.clone()
                };
                covered(&draw(&dev, &[(&one, Vec3::ONE)]))
            })
            .collect();
        let mut all: Vec<_> = halves.concat();
        all.sort();
        let expected: Vec<(u32, u32)> = (0..3).flat_map(|x| (0..3).map(move |y| (x, y))).collect();
        assert_eq!(all, expected);
    }

    #[test]
    fn back_faces_are_culled() {
        let dev = straight_device(4, 4, 4.0);
        let mut quad = pixel_rect(&dev, [0.0, 0.0, 4.0, 4.0], 1.0);
        for t in &mut quad.triangles {
            t.swap(1, 2);
        }
        assert!(covered(&draw(&dev, &[(&quad, Vec3::ONE)])).is_empty());
    }

    #[test]
    fn nearer_surface_wins_regardless_of_order_and_depth_is_exact() {
        let dev = straight_device(8, 8, 8.0);
        let near = pixel_rect(&dev, [0.0, 0.0, 8.0, 8.0], 1.0);
        let far = pixel_rect(&dev, [0.0, 0.0, 8.0, 8.0], 2.0);
        for order in [
            [(&near, Vec3::X), (&far, Vec3::Y)],
            [(&far, Vec3::Y), (&near, Vec3::X)],
        ] {
            let img = draw(&dev, &order);
            assert!(img.colour.iter().all(|c| *c == [1.0, 0.0, 0.0, 1.0]));
            // z_ndc = f (z - n) / (z (f - n)) at z = 1.
            let expected = 10.0 * (1.0 - 0.1) / (1.0 * (10.0 - 0.1));
            assert!(
                img.depth
                    .iter()
                    .all(|&d| (d as f64 - expected).abs() < 1e-7)
            );
            // Only the shared diagonal passes through pixel centres.
            let uncertain: Vec<usize> = (0..64).filter(|&i| img.uncertain[i]).collect();
            assert_eq!(uncertain, (0..8).map(|i| i * 8 + i).collect::<Vec<_>>());
        }
    }

    #[test]
    fn coplanar_surfaces_are_uncertain() {
        let dev = straight_device(4, 4, 4.0);
        let a = pixel_rect(&dev, [0.0, 0.0, 4.0, 4.0], 1.0);
        let img = draw(&dev, &[(&a, Vec3::X), (&a, Vec3::Y)]);
        assert!(img.uncertain.iter().all(|&u| u));
        // Depth test Less: the first drawn keeps the pixel.
        assert!(img.colour.iter().all(|c| c[0] == 1.0));
    }

    #[test]
    fn triangle_through_near_plane_is_clipped_not_dropped() {
        // A floor-like quad from z = 0.05 (before near = 0.1) to z = 2,
        // below the device; only its part beyond the near plane is drawn.
        let dev = straight_device(16, 16, 8.0);
        let floor = Mesh {
            positions: vec![
                Vec3::new(-1.0, 0.5, 0.05),
                Vec3::new(1.0, 0.5, 0.05),
                Vec3::new(1.0, 0.5, 2.0),
                Vec3::new(-1.0, 0.5, 2.0),
            ],
            // Normal -y (up in OpenCV's y-down device frame: towards the device).
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            ..Mesh::default()
        };
        let img = draw(&dev, &[(&floor, Vec3::ONE)]);
        // Rows v with v - cy = f * 0.5 / z, z in [0.1, 2]: v >= 8 + 2 = 10.
        for (x, y) in covered(&img) {
            assert!(y >= 10, "pixel ({x}, {y}) above the floor's horizon");
        }
        assert!(covered(&img).len() > 16 * 4);
        assert!(img.depth.iter().all(|d| (0.0..=1.0).contains(d)));
    }

    #[test]
    fn lambert_uses_world_normal_under_nonuniform_scale() {
        // A 45-degree face stretched along x: the world normal tilts.
        let t = Transform {
            translation: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: Vec3::new(2.0, 1.0, 1.0),
        };
        let n_obj = DVec3::new(1.0, 1.0, 0.0).normalize();
        let got = lambert(&normal_from_object(&t), n_obj, DVec3::Y);
        // Plane x + y = c becomes x/2 + y = c: normal (0.5, 1) / |.|.
        let expected = 1.0 / (0.25f64 + 1.0).sqrt();
        assert!((got - expected).abs() < 1e-12);
    }

    #[test]
    fn bad_scenes_are_errors() {
        let dev = straight_device(4, 4, 4.0);
        let bad = Mesh {
            positions: vec![Vec3::ZERO; 2],
            triangles: vec![[0, 1, 2]],
            ..Mesh::default()
        };
        let items = [DrawItem {
            mesh: &bad,
            transform: Transform::IDENTITY,
            albedo: Vec3::ONE,
        }];
        let scene = FlatLambertScene {
            device: &dev,
            items: &items,
            to_light: Vec3::Y,
        };
        assert_eq!(
            rasterise_flat_lambert(&scene),
            Err(SceneError::IndexOutOfRange {
                item: 0,
                triangle: 0,
                index: 2,
                vertices: 2
            })
        );
        let scene = FlatLambertScene {
            to_light: Vec3::ZERO,
            items: &[],
            ..scene
        };
        assert_eq!(
            rasterise_flat_lambert(&scene),
            Err(SceneError::BadLight(Vec3::ZERO))
        );
        let mut empty = dev.clone();
        empty.width = 0;
        let scene = FlatLambertScene {
            device: &empty,
            to_light: Vec3::Y,
            ..scene
        };
        assert!(matches!(
            rasterise_flat_lambert(&scene),
            Err(SceneError::EmptyImage { .. })
        ));
    }
}
