//! The serde shape of a scene file: every table denies unknown keys and
//! every number is checked finite while it is parsed, so that TOML's span
//! (line and column) points at the offending value.

use serde::{Deserialize, Deserializer, de};

/// Largest magnitude accepted for any number of a scene file. Larger values
/// would overflow `f32` arithmetic downstream.
pub(crate) const MAX_MAGNITUDE: f64 = 1e9;

/// A finite number of moderate magnitude (TOML allows `nan` and `inf`; a
/// scene does not).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Num(pub(crate) f64);

/// Check a parsed number: finite, and within [`MAX_MAGNITUDE`].
fn checked<E: de::Error>(x: f64) -> Result<Num, E> {
    if !x.is_finite() {
        return Err(E::custom(format!("number {x} is not finite")));
    }
    if x.abs() > MAX_MAGNITUDE {
        return Err(E::custom(format!(
            "number {x:e} is outside -{MAX_MAGNITUDE:e}..={MAX_MAGNITUDE:e}"
        )));
    }
    Ok(Num(x))
}

impl<'de> Deserialize<'de> for Num {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        checked(f64::deserialize(d)?)
    }
}

/// Three finite numbers.
pub(crate) type N3 = [Num; 3];

/// The whole file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SceneDef {
    pub(crate) name: String,
    #[serde(default)]
    pub(crate) ambient: Option<N3>,
    /// `"direct"` (the default) or `"global"`.
    #[serde(default)]
    pub(crate) illumination: showcase_proto::IlluminationMode,
    /// The largest radiosity patch (m^2) in global mode.
    #[serde(default)]
    pub(crate) patch_area: Option<Num>,
    #[serde(default, rename = "object")]
    pub(crate) objects: Vec<ObjectDef>,
    #[serde(default, rename = "light")]
    pub(crate) lights: Vec<LightDef>,
    #[serde(default, rename = "projector")]
    pub(crate) projectors: Vec<DeviceDef>,
    #[serde(default, rename = "camera")]
    pub(crate) cameras: Vec<DeviceDef>,
    #[serde(default, rename = "face")]
    pub(crate) faces: Vec<FaceDef>,
    #[serde(default, rename = "observer")]
    pub(crate) observers: Vec<ObserverDef>,
}

/// `kind = "real" | "virtual"`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub(crate) enum KindDef {
    Real,
    Virtual,
}

/// `scale = 2.0` or `scale = [1, 2, 1]`.
#[derive(Clone, Copy, Debug)]
pub(crate) enum ScaleDef {
    Uniform(Num),
    PerAxis(N3),
}

impl<'de> Deserialize<'de> for ScaleDef {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct ScaleVisitor;
        impl<'de> de::Visitor<'de> for ScaleVisitor {
            type Value = ScaleDef;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a number or an array of 3 numbers")
            }
            fn visit_f64<E: de::Error>(self, x: f64) -> Result<ScaleDef, E> {
                checked(x).map(ScaleDef::Uniform)
            }
            fn visit_i64<E: de::Error>(self, x: i64) -> Result<ScaleDef, E> {
                self.visit_f64(x as f64)
            }
            fn visit_u64<E: de::Error>(self, x: u64) -> Result<ScaleDef, E> {
                self.visit_f64(x as f64)
            }
            fn visit_seq<A: de::SeqAccess<'de>>(self, mut seq: A) -> Result<ScaleDef, A::Error> {
                let mut out = [Num(0.0); 3];
                for (i, slot) in out.iter_mut().enumerate() {
                    *slot = seq
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                if seq.next_element::<de::IgnoredAny>()?.is_some() {
                    return Err(de::Error::invalid_length(4, &self));
                }
                Ok(ScaleDef::PerAxis(out))
            }
        }
        d.deserialize_any(ScaleVisitor)
    }
}

/// Where the mesh's local origin is put before the transform applies.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub(crate) enum AnchorDef {
    /// Keep the mesh's own origin.
    #[default]
    Origin,
    /// The centre of the selected parts' bounding box.
    Center,
    /// The centre of the bottom face (lowest y) of the bounding box.
    Bottom,
}

/// A procedural albedo texture.
#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub(crate) enum TextureDef {
    Checker { cells: u32, a: N3, b: N3 },
    Wood { light: N3, dark: N3, rings: Num },
}

/// One `[[object]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ObjectDef {
    pub(crate) name: String,
    pub(crate) mesh: String,
    pub(crate) kind: KindDef,
    #[serde(default)]
    pub(crate) translation: Option<N3>,
    #[serde(default)]
    pub(crate) rotation_deg: Option<N3>,
    #[serde(default)]
    pub(crate) rotation_quat: Option<[Num; 4]>,
    #[serde(default)]
    pub(crate) scale: Option<ScaleDef>,
    #[serde(default)]
    pub(crate) normalize_height: Option<Num>,
    #[serde(default)]
    pub(crate) anchor: AnchorDef,
    #[serde(default)]
    pub(crate) parts: Option<Vec<String>>,
    #[serde(default)]
    pub(crate) exclude_parts: Option<Vec<String>>,
    #[serde(default)]
    pub(crate) albedo: Option<N3>,
    #[serde(default)]
    pub(crate) texture: Option<TextureDef>,
    #[serde(default)]
    pub(crate) reflectance_map: Option<String>,
    #[serde(default)]
    pub(crate) specular: bool,
    #[serde(default)]
    pub(crate) reflective: bool,
    #[serde(default)]
    pub(crate) emission: Option<N3>,
    #[serde(default)]
    pub(crate) size: Option<[Num; 2]>,
    #[serde(default)]
    pub(crate) subdivisions: Option<u32>,
    #[serde(default)]
    pub(crate) radius: Option<Num>,
    #[serde(default)]
    pub(crate) segments: Option<u32>,
}

/// `type = "point" | "spot" | "area"`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub(crate) enum LightType {
    Point,
    Spot,
    Area,
}

/// One `[[light]]`: a flat table whose required keys depend on `type`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LightDef {
    pub(crate) name: String,
    #[serde(rename = "type")]
    pub(crate) kind: LightType,
    #[serde(default)]
    pub(crate) position: Option<N3>,
    #[serde(default)]
    pub(crate) intensity: Option<N3>,
    #[serde(default)]
    pub(crate) direction: Option<N3>,
    #[serde(default)]
    pub(crate) inner_deg: Option<Num>,
    #[serde(default)]
    pub(crate) outer_deg: Option<Num>,
    #[serde(default)]
    pub(crate) corner: Option<N3>,
    #[serde(default)]
    pub(crate) edge_u: Option<N3>,
    #[serde(default)]
    pub(crate) edge_v: Option<N3>,
    #[serde(default)]
    pub(crate) radiance: Option<N3>,
    #[serde(default)]
    pub(crate) samples: Option<u32>,
}

/// `look_at = { eye, target, up, fov_deg }` (horizontal field of view).
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LookAtDef {
    pub(crate) eye: N3,
    pub(crate) target: N3,
    #[serde(default)]
    pub(crate) up: Option<N3>,
    pub(crate) fov_deg: Num,
}

/// One `[[projector]]` or `[[camera]]`: geometry plus the response keys of
/// both kinds (a key of the other kind is rejected after parsing).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct DeviceDef {
    pub(crate) name: String,
    #[serde(default)]
    pub(crate) width: Option<u32>,
    #[serde(default)]
    pub(crate) height: Option<u32>,
    #[serde(default)]
    pub(crate) look_at: Option<LookAtDef>,
    #[serde(default)]
    pub(crate) camera_matrix: Option<[N3; 3]>,
    #[serde(default)]
    pub(crate) rotation: Option<[N3; 3]>,
    #[serde(default)]
    pub(crate) translation: Option<N3>,
    #[serde(default)]
    pub(crate) dist_coeffs: Option<[Num; 5]>,
    #[serde(default)]
    pub(crate) calibration: Option<String>,
    #[serde(default)]
    pub(crate) near: Option<Num>,
    #[serde(default)]
    pub(crate) far: Option<Num>,
    #[serde(default)]
    pub(crate) gamma: Option<Num>,
    // Projector response.
    #[serde(default)]
    pub(crate) eta: Option<Num>,
    #[serde(default)]
    pub(crate) black_level: Option<Num>,
    #[serde(default)]
    pub(crate) wheel_segments: Option<Vec<N3>>,
    #[serde(default)]
    pub(crate) wheel_period_s: Option<Num>,
    /// The projector's own light per channel (the simulated device).
    #[serde(default)]
    pub(crate) photometry: Option<CrtDef>,
    /// Or the profile `calibrate --photometric` measured of it.
    #[serde(default)]
    pub(crate) photometric_profile: Option<String>,
    // Camera response.
    #[serde(default)]
    pub(crate) gamma_rgb: Option<N3>,
    #[serde(default)]
    pub(crate) knee: Option<Num>,
    #[serde(default)]
    pub(crate) shoulder: Option<Num>,
    #[serde(default)]
    pub(crate) gain: Option<Num>,
    #[serde(default)]
    pub(crate) exposure_s: Option<Num>,
    #[serde(default)]
    pub(crate) read_noise: Option<Num>,
    #[serde(default)]
    pub(crate) shot_noise: Option<Num>,
    #[serde(default)]
    pub(crate) bits: Option<u32>,
}

/// `screen = { origin, right, down }`.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ScreenDef {
    pub(crate) origin: N3,
    pub(crate) right: N3,
    pub(crate) down: N3,
}

/// `mirror = { point, normal }`.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct MirrorDef {
    pub(crate) point: N3,
    pub(crate) normal: N3,
}

/// One `[[face]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct FaceDef {
    pub(crate) name: String,
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) screen: ScreenDef,
    pub(crate) mirror: MirrorDef,
    #[serde(default)]
    pub(crate) gamma: Option<Num>,
    #[serde(default)]
    pub(crate) crt: Option<CrtDef>,
    #[serde(default)]
    pub(crate) beam_splitter: Option<SplitterDef>,
    #[serde(default)]
    pub(crate) photometric_profile: Option<String>,
}

/// `[face.crt]`: light per drive value, per channel.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CrtDef {
    pub(crate) gamma: N3,
    pub(crate) peak: N3,
    #[serde(default)]
    pub(crate) black_level: Option<N3>,
}

/// `[face.beam_splitter]`: transmission and reflection per channel.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SplitterDef {
    pub(crate) transmission: N3,
    pub(crate) reflection: N3,
}

/// One `[[observer]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ObserverDef {
    pub(crate) name: String,
    pub(crate) position: N3,
    #[serde(default)]
    pub(crate) look_at: Option<N3>,
    #[serde(default)]
    pub(crate) up: Option<N3>,
    #[serde(default)]
    pub(crate) orientation_quat: Option<[Num; 4]>,
    #[serde(default)]
    pub(crate) ipd: Option<Num>,
}

/// The calibration output of `showcase-master calibrate` (OpenCV naming,
/// `x_cam = R X + t`). Extra keys such as `projection`, `rms_px` and
/// `residuals_px` are read but not used: `projection` is checked against
/// `K [R | t]`.
#[derive(Debug, Deserialize)]
pub(crate) struct CalibrationDef {
    pub(crate) camera_matrix: [[f64; 3]; 3],
    #[serde(default)]
    pub(crate) dist_coeffs: Option<Vec<f64>>,
    pub(crate) rotation: [[f64; 3]; 3],
    pub(crate) translation: [f64; 3],
    #[serde(default)]
    pub(crate) projection: Option<[[f64; 4]; 3]>,
    #[serde(default)]
    pub(crate) width: Option<u32>,
    #[serde(default)]
    pub(crate) height: Option<u32>,
}
