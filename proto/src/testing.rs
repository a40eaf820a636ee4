//! Proptest strategies that generate valid scenes and messages, for
//! round-trip and robustness tests (feature `testing`).

use crate::message::*;
use crate::scene::*;
use glam::{DVec3, Quat, Vec2, Vec3};
use proptest::collection::vec;
use proptest::prelude::*;

/// A finite float in a range typical of scene coordinates.
pub fn coord() -> impl Strategy<Value = f32> {
    -10.0f32..10.0
}

/// A finite point or vector.
pub fn vec3() -> impl Strategy<Value = Vec3> {
    (coord(), coord(), coord()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

/// A non-negative colour with components in `[0, max]`.
pub fn colour(max: f32) -> impl Strategy<Value = Vec3> {
    (0.0..=max, 0.0..=max, 0.0..=max).prop_map(|(r, g, b)| Vec3::new(r, g, b))
}

/// A unit quaternion.
pub fn rotation() -> impl Strategy<Value = Quat> {
    (vec3(), -3.1f32..3.1).prop_map(|(axis, angle)| {
        Quat::from_axis_angle(axis.try_normalize().unwrap_or(Vec3::Y), angle)
    })
}

/// A non-degenerate transform.
pub fn transform() -> impl Strategy<Value = Transform> {
    (vec3(), rotation(), 0.1f32..4.0).prop_map(|(translation, rotation, s)| Transform {
        translation,
        rotation,
        scale: Vec3::splat(s),
    })
}

/// A small valid mesh (possibly with normals and uvs).
pub fn mesh() -> impl Strategy<Value = Mesh> {
    (1usize..24, any::<bool>(), any::<bool>())
        .prop_flat_map(|(n, with_normals, with_uvs)| {
            (
                vec(vec3(), n),
                vec(vec3(), if with_normals { n } else { 0 }),
                vec(
                    (0.0f32..1.0, 0.0f32..1.0).prop_map(|(u, v)| Vec2::new(u, v)),
                    if with_uvs { n } else { 0 },
                ),
                vec(proptest::array::uniform3(0..n as u32), 0..32),
            )
        })
        .prop_map(|(positions, normals, uvs, triangles)| Mesh {
            positions,
            normals,
            uvs,
            triangles,
        })
}

/// A valid material.
pub fn material() -> impl Strategy<Value = Material> {
    (
        colour(0.99),
        prop::option::of(prop_oneof![
            (1u32..16, colour(1.0), colour(1.0)).prop_map(|(cells, a, b)| AlbedoTexture::Checker {
                cells,
                a,
                b
            }),
            (colour(1.0), colour(1.0), 1.0f32..20.0)
                .prop_map(|(light, dark, rings)| { AlbedoTexture::Wood { light, dark, rings } }),
        ]),
        prop::option::of("[a-z]{1,12}"),
        colour(20.0),
        any::<bool>(),
        any::<bool>(),
    )
        .prop_map(
            |(albedo, texture, reflectance_map, emission, specular, reflective)| Material {
                albedo,
                texture,
                reflectance_map,
                emission,
                specular,
                reflective,
            },
        )
}

/// A valid light of any type.
pub fn light() -> impl Strategy<Value = Light> {
    prop_oneof![
        (vec3(), colour(10.0)).prop_map(|(position, intensity)| Light::Point {
            position,
            intensity
        }),
        (vec3(), rotation(), colour(10.0), 0.0f32..40.0, 0.0f32..40.0).prop_map(
            |(position, r, intensity, a, b)| Light::Spot {
                position,
                direction: r * Vec3::NEG_Y,
                intensity,
                inner_deg: a.min(b),
                outer_deg: a.max(b) + 1.0,
            }
        ),
        (
            vec3(),
            rotation(),
            0.01f32..1.0,
            0.01f32..1.0,
            colour(20.0),
            1u32..64
        )
            .prop_map(|(corner, r, su, sv, radiance, samples)| Light::Area {
                corner,
                edge_u: r * Vec3::X * su,
                edge_v: r * Vec3::Z * sv,
                radiance,
                samples,
            }),
    ]
}

/// A valid pinhole device looking from one random point at another.
pub fn device() -> impl Strategy<Value = PinholeDevice> {
    (vec3(), vec3(), 20.0f64..100.0, 16u32..2048, 16u32..2048)
        .prop_filter("eye and target apart, view not vertical", |(e, t, ..)| {
            let d = (*t - *e).normalize_or_zero();
            (*t - *e).length() > 0.1 && d.y.abs() < 0.95
        })
        .prop_map(|(eye, target, fov, w, h)| {
            PinholeDevice::look_at(eye.as_dvec3(), target.as_dvec3(), DVec3::Y, fov, w, h)
        })
}

/// A valid CRT face.
pub fn face() -> impl Strategy<Value = CrtFace> {
    (vec3(), rotation(), 0.1f32..1.0, vec3(), rotation()).prop_map(
        |(origin, r, size, point, mr)| CrtFace {
            name: String::new(),
            screen: Rect3 {
                origin,
                right: r * Vec3::X * size,
                down: r * Vec3::NEG_Y * size * 0.75,
            },
            mirror: Plane::from_point_normal(point, mr * Vec3::Y),
            width: 1024,
            height: 768,
            photometry: CrtPhotometry::nominal(2.2),
        },
    )
}

/// A head pose.
pub fn pose() -> impl Strategy<Value = Pose> {
    (vec3(), rotation()).prop_map(|(position, orientation)| Pose {
        position,
        orientation,
    })
}

fn named<T: std::fmt::Debug>(
    prefix: &'static str,
    items: impl Strategy<Value = Vec<T>>,
) -> impl Strategy<Value = Vec<(String, T)>> {
    items.prop_map(move |v| {
        v.into_iter()
            .enumerate()
            .map(|(i, t)| (format!("{prefix}-{i}"), t))
            .collect()
    })
}

/// A valid showcase: objects refer to its meshes, names are unique.
pub fn showcase() -> impl Strategy<Value = Showcase> {
    (
        vec(mesh(), 1..4),
        vec((material(), transform(), any::<bool>(), 0usize..4), 0..6),
        named("light", vec(light(), 0..4)),
        named("projector", vec(device(), 0..3)),
        named("camera", vec(device(), 0..2)),
        named("face", vec(face(), 0..3)),
        named("observer", vec((pose(), 0.05f32..0.08), 0..3)),
        colour(0.2),
    )
        .prop_map(
            |(meshes, objects, lights, projectors, cameras, faces, observers, ambient)| {
                let mut s = Showcase {
                    name: "generated".into(),
                    ambient,
                    ..Showcase::default()
                };
                let ids: Vec<MeshId> = meshes.into_iter().map(|m| s.add_mesh(m)).collect();
                for (i, (material, transform, real, m)) in objects.into_iter().enumerate() {
                    s.objects.push(Object {
                        name: format!("object-{i}"),
                        mesh: ids[m % ids.len()],
                        material,
                        kind: if real {
                            ObjectKind::Real
                        } else {
                            ObjectKind::Virtual
                        },
                        transform,
                    });
                }
                s.lights = lights
                    .into_iter()
                    .map(|(name, light)| LightSource { name, light })
                    .collect();
                s.projectors = projectors
                    .into_iter()
                    .map(|(name, device)| Projector {
                        name,
                        device,
                        response: ProjectorResponse {
                            wheel_segments: vec![Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE],
                            ..ProjectorResponse::default()
                        },
                    })
                    .collect();
                s.cameras = cameras
                    .into_iter()
                    .map(|(name, device)| Camera {
                        name,
                        device,
                        response: CameraResponse::default(),
                    })
                    .collect();
                s.faces = faces
                    .into_iter()
                    .map(|(name, f)| CrtFace { name, ..f })
                    .collect();
                s.observers = observers
                    .into_iter()
                    .map(|(name, (head, ipd))| Observer { name, head, ipd })
                    .collect();
                s
            },
        )
}

/// A frame state that is valid for `scene`.
pub fn frame_state_for(
    scene: &Showcase,
    version: u64,
) -> impl Strategy<Value = FrameState> + use<> {
    let heads = scene.observers.len();
    let objects = scene.objects.len() as u32;
    (
        any::<u64>(),
        0.0f64..1e6,
        vec(pose(), heads),
        named("light", vec(light(), 0..4)),
        vec(
            (0..objects.max(1), transform()),
            0..=(objects as usize).min(4),
        ),
        prop::option::of(any::<u64>()),
    )
        .prop_map(
            move |(frame, time_s, heads, lights, transforms, tracking_time_ns)| FrameState {
                frame,
                time_s,
                scene_version: version,
                heads,
                lights: lights
                    .into_iter()
                    .map(|(name, light)| LightSource { name, light })
                    .collect(),
                object_transforms: transforms
                    .into_iter()
                    .map(|(object, transform)| ObjectTransform { object, transform })
                    .collect(),
                tracking_time_ns,
                illumination_version: None,
            },
        )
}

/// A valid snapshot, with or without the frame in flight.
pub fn snapshot() -> impl Strategy<Value = SceneSnapshot> {
    (showcase(), any::<u64>()).prop_flat_map(|(showcase, version)| {
        let frame = frame_state_for(&showcase, version);
        (Just(showcase), Just(version), prop::option::of(frame)).prop_map(
            |(showcase, version, current)| SceneSnapshot {
                version,
                showcase,
                current,
                maps: Vec::new(),
            },
        )
    })
}

/// Any valid global-illumination solution, whole or a delta.
pub fn illumination() -> impl Strategy<Value = crate::message::Illumination> {
    use crate::message::{
        ElementChange, ElementLight, Illumination, IlluminationBody, IlluminationMesh,
    };
    let rgb = || [-1e3f32..1e3, -1e3f32..1e3, -1e3f32..1e3];
    let value = move || (rgb(), rgb()).prop_map(|(add, cabinet)| ElementLight { add, cabinet });
    let full = (
        1e-4f64..1.0,
        0u32..=6,
        0.0f64..1e-2,
        prop::collection::vec(value(), 0..64),
    )
        .prop_map(
            |(max_patch_area, element_depth, min_element_area, values)| IlluminationBody::Full {
                mesh: IlluminationMesh {
                    max_patch_area,
                    element_depth,
                    min_element_area,
                },
                values,
            },
        );
    let delta = (
        any::<u64>(),
        prop::collection::btree_map(any::<u32>(), value(), 0..64),
    )
        .prop_map(|(base, changes)| IlluminationBody::Delta {
            base,
            changes: changes
                .into_iter()
                .map(|(element, value)| ElementChange { element, value })
                .collect(),
        });
    (any::<u64>(), any::<u64>(), prop_oneof![full, delta]).prop_map(
        |(version, scene_version, body)| Illumination {
            version,
            scene_version,
            body,
        },
    )
}

/// Any valid message.
pub fn message() -> impl Strategy<Value = Message> {
    prop_oneof![
        (
            "[a-z0-9-]{1,32}",
            any::<u32>(),
            0u8..3,
            any::<bool>(),
            ".{0,20}"
        )
            .prop_map(
                |(node, protocol_version, role, gpu, adapter)| Message::Hello(Hello {
                    protocol_version,
                    node,
                    role: [Role::Face, Role::Projector, Role::Camera][role as usize],
                    capabilities: Capabilities { gpu, adapter },
                })
            ),
        (any::<u32>(), 1.0f32..500.0, 1.0f32..1000.0).prop_map(
            |(protocol_version, target_hz, deadline_ms)| Message::Welcome(Welcome {
                protocol_version,
                target_hz,
                deadline_ms
            })
        ),
        snapshot().prop_map(|s| Message::SceneSnapshot(Box::new(s))),
        showcase()
            .prop_flat_map(|s| frame_state_for(&s, 1))
            .prop_map(|f| Message::FrameState(Box::new(f))),
        (any::<u64>(), any::<u64>())
            .prop_map(|(frame, output_hash)| Message::Ready(Ready { frame, output_hash })),
        any::<u64>().prop_map(|frame| Message::Swap(Swap { frame })),
        (any::<u64>(), 0.0f32..1e3, 0.0f32..1e3, any::<u64>()).prop_map(
            |(frame, render_ms, barrier_wait_ms, present_time_ns)| {
                Message::NodeStats(NodeStats {
                    frame,
                    render_ms,
                    barrier_wait_ms,
                    present_time_ns,
                })
            }
        ),
        (any::<u64>(), any::<u64>()).prop_map(|(id, master_send_ns)| Message::ClockProbe(
            ClockProbe { id, master_send_ns }
        )),
        (any::<u64>(), any::<u64>(), any::<u64>(), any::<u64>()).prop_map(|(id, a, b, c)| {
            Message::ClockReply(ClockReply {
                id,
                master_send_ns: a,
                node_recv_ns: b,
                node_send_ns: c,
            })
        }),
        ".{0,64}".prop_map(|reason| Message::Bye(Bye { reason })),
        illumination().prop_map(|i| Message::Illumination(Box::new(i))),
        any::<u64>().prop_map(|version| Message::IlluminationResync(
            crate::message::IlluminationResync { version }
        )),
        any::<u64>().prop_map(|version| Message::IlluminationReady(
            crate::message::IlluminationReady { version }
        )),
        capture_message(),
    ]
}

/// A valid projector pattern.
pub fn pattern() -> impl Strategy<Value = crate::capture::Pattern> {
    use crate::capture::Pattern;
    let level = prop::array::uniform3(0.0f32..=1.0);
    prop_oneof![
        level.clone().prop_map(|level| Pattern::Full { level }),
        (1u32..24, 1u32..24, level.clone(), any::<u64>()).prop_map(|(w, h, level, bits)| {
            Pattern::mask(w, h, (0..w * h).map(|i| bits >> (i % 64) & 1 == 1), level)
        }),
        (any::<bool>(), 0u32..16, any::<bool>(), level).prop_map(
            |(columns, bit, inverted, level)| Pattern::GrayCode {
                columns,
                bit,
                inverted,
                level
            }
        ),
    ]
}

/// One valid frame's codes, at most 16 x 16 pixels.
pub fn frame_codes() -> impl Strategy<Value = crate::capture::FrameCodes> {
    (1u32..16, 1u32..16, 1u32..=16).prop_flat_map(|(width, height, bits)| {
        let max = ((1u32 << bits) - 1) as u16;
        prop::collection::vec(prop::array::uniform3(0..=max), (width * height) as usize).prop_map(
            move |codes| crate::capture::FrameCodes {
                width,
                height,
                bits,
                codes,
            },
        )
    })
}

/// Any valid capture message.
pub fn capture_message() -> impl Strategy<Value = Message> {
    use crate::capture::*;
    prop_oneof![
        (any::<u64>(), pattern())
            .prop_map(|(id, pattern)| Message::ShowPattern(Box::new(ShowPattern { id, pattern }))),
        any::<u64>().prop_map(|id| Message::PatternShown(PatternShown { id })),
        (
            any::<u64>(),
            1e-4f64..1.0,
            1e-3f64..1e3,
            0.0f64..0.1,
            1u32..=MAX_CAPTURE_FRAMES
        )
            .prop_map(|(id, exposure_s, gain, period_s, count)| {
                Message::CaptureFrames(CaptureFrames {
                    id,
                    exposure_s,
                    gain,
                    period_s,
                    count,
                })
            }),
        (any::<u64>(), frame_codes(), 1usize..200).prop_map(|(id, f, size)| {
            let c = split_frame(id, 0, 1, &f, size).swap_remove(0);
            Message::FrameChunk(Box::new(c))
        }),
        (any::<u64>(), ".{0,64}")
            .prop_map(|(id, reason)| Message::CaptureFailed(CaptureFailed { id, reason })),
    ]
}
