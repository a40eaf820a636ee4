//! A camera node backed by a camera of this machine: a real V4L2 camera
//! (cargo feature `v4l2`, Linux) or a recorded camera (a folder replayed,
//! [`RecordedCamera`]), answering the master's `CaptureFrames` through
//! [`CaptureDevices`](super::CaptureDevices) as the sim's
//! [`super::SimCameraNode`] does.
//!
//! Each request fixes the gain and the exposure before its series
//! ([`ManualCamera`]; auto exposure, auto gain and auto white balance stay
//! off), then takes its frames, a live camera waiting for each frame's
//! start on the display period's spread ([`CaptureFrames::start_s`]). The
//! camera's size must be the scene camera's: a mismatch stops the capture
//! with what to change. `showcase-node --camera SPEC` ([`CameraSpec`])
//! selects one.

use crate::camera::recorded::RecordedCamera;
use showcase_light::hardware::{CameraDevice, CameraFrame};
use showcase_proto::capture::{CaptureFrames, Pattern};
use showcase_proto::{Camera, Showcase};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A camera whose exposure and gain a capture fixes. Errors are words for
/// the master's operator.
pub trait ManualCamera: CameraDevice + Send {
    /// What the camera is, for messages ("the V4L2 camera /dev/video0").
    fn describe(&self) -> String;
    /// What to change so that the camera delivers `width x height` frames.
    fn resize_hint(&self, width: u32, height: u32) -> String;
    /// Fix the exposure of the frames that follow (seconds).
    fn set_exposure(&mut self, exposure_s: f64) -> Result<(), String>;
    /// Fix the gain of the frames that follow: the calibrated gain (signal
    /// per unit radiance and second) the master's request carries.
    fn set_gain(&mut self, gain: f64) -> Result<(), String>;
    /// Whether frames follow the wall clock (a live camera: the node waits
    /// for each frame's start), not a replay.
    fn live(&self) -> bool;
}

impl ManualCamera for RecordedCamera {
    fn describe(&self) -> String {
        format!("the recorded camera {}", self.dir().display())
    }
    fn resize_hint(&self, width: u32, height: u32) -> String {
        format!(
            "record the camera again at {width}x{height} (`showcase-camera record --camera FILE` \
             takes the scene camera's size), or use a scene whose camera is {}x{}",
            self.index().device.width,
            self.index().device.height
        )
    }
    fn set_exposure(&mut self, exposure_s: f64) -> Result<(), String> {
        self.check_exposure(exposure_s)
            .map_err(|e| format!("a recorded camera cannot change its exposure: {e}"))
    }
    fn set_gain(&mut self, gain: f64) -> Result<(), String> {
        self.check_gain(gain).map_err(|e| e.to_string())
    }
    fn live(&self) -> bool {
        false
    }
}

#[cfg(all(feature = "v4l2", target_os = "linux"))]
impl ManualCamera for crate::camera::v4l2::V4l2Camera {
    fn describe(&self) -> String {
        format!("the V4L2 camera {}", self.path().display())
    }
    fn resize_hint(&self, width: u32, height: u32) -> String {
        format!(
            "start the node with --camera v4l2:{}:{width}x{height} (the camera's calibration \
             holds for one size: calibrate it at that size)",
            self.path().display()
        )
    }
    fn set_exposure(&mut self, exposure_s: f64) -> Result<(), String> {
        crate::camera::v4l2::V4l2Camera::set_exposure(self, exposure_s).map_err(|e| e.to_string())
    }
    /// The gain control stays at the value the camera was calibrated at
    /// (`--camera-gain`, set when it opened): V4L2 gain controls have no
    /// common unit, so another calibrated gain cannot be turned into a
    /// control value and is refused.
    fn set_gain(&mut self, gain: f64) -> Result<(), String> {
        let calibrated = f64::from(self.response().gain);
        if (gain - calibrated).abs() > 1e-3 * calibrated.abs().max(1e-9) || gain.is_nan() {
            return Err(format!(
                "{}: the capture asks gain {gain}, the camera's calibration has gain {calibrated}: \
                 the camera's gain control stays at its calibrated value (--camera-gain); \
                 calibrate the camera at the gain the capture needs",
                self.describe()
            ));
        }
        Ok(())
    }
    fn live(&self) -> bool {
        true
    }
}

/// Opens a camera for the scene's camera (its size, its calibration).
pub type CameraOpener<C> = Box<dyn FnMut(&Camera) -> Result<C, String> + Send>;

/// A camera node's devices backed by a [`ManualCamera`].
pub struct CameraNode<C: ManualCamera> {
    name: String,
    camera: Option<C>,
    open: Option<CameraOpener<C>>,
    /// The scene's camera the open camera was opened for (lazy nodes).
    opened_for: Option<Camera>,
    scene: Option<Arc<Showcase>>,
}

impl<C: ManualCamera> std::fmt::Debug for CameraNode<C> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "CameraNode({})", self.name)
    }
}

impl<C: ManualCamera> CameraNode<C> {
    /// The node of the scene's camera `name`, backed by `camera`.
    pub fn new(name: &str, camera: C) -> Self {
        Self {
            name: name.into(),
            camera: Some(camera),
            open: None,
            opened_for: None,
            scene: None,
        }
    }

    /// The node of camera `name`, opening its camera at the first capture
    /// with the scene camera's size and calibration, and again (after
    /// closing it) at the first capture after the scene's camera changed:
    /// a new calibration, another size.
    pub fn lazy(name: &str, open: CameraOpener<C>) -> Self {
        Self {
            name: name.into(),
            camera: None,
            open: Some(open),
            opened_for: None,
            scene: None,
        }
    }

    /// The camera, once open.
    pub fn camera(&self) -> Option<&C> {
        self.camera.as_ref()
    }

    /// The scene's camera of this node.
    fn scene_camera(&self) -> Result<Camera, String> {
        let scene = self
            .scene
            .as_ref()
            .ok_or("no scene yet: the master has not sent one")?;
        scene
            .cameras
            .iter()
            .find(|c| c.name == self.name)
            .cloned()
            .ok_or_else(|| {
                format!(
                    "the scene has no camera {:?}: check this node's output in the cluster config",
                    self.name
                )
            })
    }

    /// The camera, opened for the scene's camera and checked against its
    /// size.
    fn ready(&mut self) -> Result<&mut C, String> {
        let want = self.scene_camera()?;
        if self.open.is_some() && self.opened_for.as_ref() != Some(&want) {
            // Closed before it is opened again: a device streams to one
            // opener at a time.
            self.camera = None;
        }
        if self.camera.is_none() {
            let open = self
                .open
                .as_mut()
                .ok_or("the camera could not be opened before")?;
            self.camera = Some(open(&want)?);
            self.opened_for = Some(want.clone());
        }
        let camera = self.camera.as_mut().expect("opened above");
        let (w, h) = (camera.device().width, camera.device().height);
        let (sw, sh) = (want.device.width, want.device.height);
        if (w, h) != (sw, sh) {
            return Err(format!(
                "{} delivers {w}x{h} frames, the scene's camera {:?} is {sw}x{sh}: {}",
                camera.describe(),
                want.name,
                camera.resize_hint(sw, sh)
            ));
        }
        Ok(camera)
    }
}

impl<C: ManualCamera> super::CaptureDevices for CameraNode<C> {
    fn set_scene(&mut self, scene: Arc<Showcase>) {
        self.scene = Some(scene);
    }
    fn show(&mut self, _: &Pattern) -> Result<(), String> {
        Err(format!(
            "{:?} is a camera node; patterns need a projector node",
            self.name
        ))
    }
    fn capture(&mut self, request: &CaptureFrames) -> Result<Vec<CameraFrame>, String> {
        let camera = self.ready()?;
        // Gain and exposure fixed before the series, for all of it.
        camera.set_gain(request.gain)?;
        camera.set_exposure(request.exposure_s)?;
        let live = camera.live();
        let t0 = Instant::now();
        let mut frames = Vec::with_capacity(request.count as usize);
        for k in 0..request.count {
            let start = request.start_s(k);
            if live {
                // Frame k starts at its place on the display period's
                // spread (the camera takes the next frame begun after).
                let at = t0 + Duration::from_secs_f64(start.clamp(0.0, 3600.0));
                std::thread::sleep(at.saturating_duration_since(Instant::now()));
            }
            let frame = camera
                .capture(start, request.exposure_s)
                .map_err(|e| format!("frame {k} of {}: {e}", request.count))?;
            frames.push(frame);
        }
        Ok(frames)
    }
}

/// Which camera a camera node hosts (`showcase-node --camera`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CameraSpec {
    /// `v4l2:/dev/videoN[:WIDTHxHEIGHT[:FORMAT]]`.
    V4l2 {
        /// The device node.
        path: PathBuf,
        /// The size to ask for (default: the scene camera's).
        size: Option<(u32, u32)>,
        /// The pixel format (default: the best offered).
        format: Option<String>,
    },
    /// `recorded:DIR`.
    Recorded(PathBuf),
}

impl std::str::FromStr for CameraSpec {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let usage = "expected v4l2:/dev/videoN[:WIDTHxHEIGHT[:FORMAT]] or recorded:DIR";
        if let Some(dir) = s.strip_prefix("recorded:") {
            if dir.is_empty() {
                return Err(format!("--camera {s}: the folder is missing; {usage}"));
            }
            return Ok(CameraSpec::Recorded(dir.into()));
        }
        let Some(rest) = s.strip_prefix("v4l2:") else {
            return Err(format!("--camera {s}: {usage}"));
        };
        let mut parts = rest.split(':');
        let path = parts.next().unwrap_or_default();
        if path.is_empty() {
            return Err(format!("--camera {s}: the device node is missing; {usage}"));
        }
        let size = parts
            .next()
            .map(|size| {
                size.split_once(['x', 'X'])
                    .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)))
                    .filter(|(w, h)| *w > 0 && *h > 0)
                    .ok_or_else(|| format!("--camera {s}: size {size:?} is not WIDTHxHEIGHT"))
            })
            .transpose()?;
        let format = parts.next().map(str::to_string);
        if parts.next().is_some() {
            return Err(format!("--camera {s}: too many ':' parts; {usage}"));
        }
        Ok(CameraSpec::V4l2 {
            path: path.into(),
            size,
            format,
        })
    }
}

/// Settings of a V4L2 camera node beyond its [`CameraSpec`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct V4l2NodeOptions {
    /// The gain control's value the camera was calibrated at (`None`:
    /// left as it is; auto gain is off either way).
    pub gain: Option<i32>,
    /// Fixed white balance in kelvin (`None`: left; auto is off).
    pub white_balance_k: Option<i32>,
}

/// The capture devices of the camera node of the scene's camera `name`
/// hosting `spec`'s camera. A recording is opened (and checked) now; a
/// V4L2 camera at the first capture, with the scene camera's size and
/// calibration.
pub fn camera_node(
    name: &str,
    spec: &CameraSpec,
    options: V4l2NodeOptions,
) -> Result<super::CaptureHost, String> {
    match spec {
        CameraSpec::Recorded(dir) => {
            let camera = RecordedCamera::open(dir).map_err(|e| e.to_string())?;
            Ok(super::CaptureHost::new(CameraNode::new(name, camera)))
        }
        CameraSpec::V4l2 { path, size, format } => v4l2_node(name, path, *size, format, options),
    }
}

#[cfg(not(all(feature = "v4l2", target_os = "linux")))]
fn v4l2_node(
    _name: &str,
    path: &std::path::Path,
    _size: Option<(u32, u32)>,
    _format: &Option<String>,
    _options: V4l2NodeOptions,
) -> Result<super::CaptureHost, String> {
    Err(format!(
        "--camera v4l2:{}: this showcase-node was built without V4L2: build it with \
         `--features v4l2` (Linux), or replay a recording with --camera recorded:DIR",
        path.display()
    ))
}

#[cfg(all(feature = "v4l2", target_os = "linux"))]
fn v4l2_node(
    name: &str,
    path: &std::path::Path,
    size: Option<(u32, u32)>,
    format: &Option<String>,
    options: V4l2NodeOptions,
) -> Result<super::CaptureHost, String> {
    use crate::camera::decode::PixelFormat;
    use crate::camera::v4l2::{V4l2Camera, V4l2Config};
    let format = format
        .as_deref()
        .map(|f| {
            PixelFormat::parse(f).ok_or_else(|| {
                format!(
                    "--camera v4l2:{}: format {f:?} is not one of YUYV, UYVY, MJPG, JPEG, NV12, \
                     YU12, GREY, Y16, RGB24, BGR24",
                    path.display()
                )
            })
        })
        .transpose()?;
    let path = path.to_path_buf();
    let open = move |camera: &Camera| -> Result<V4l2Camera, String> {
        let (sw, sh) = (camera.device.width, camera.device.height);
        if let Some((w, h)) = size
            && (w, h) != (sw, sh)
        {
            return Err(format!(
                "--camera v4l2:{}:{w}x{h} asks {w}x{h} frames, the scene's camera {:?} is \
                 {sw}x{sh}: start the node with --camera v4l2:{}:{sw}x{sh} (and calibrate the \
                 camera at that size), or change the scene's camera",
                path.display(),
                camera.name,
                path.display()
            ));
        }
        let mut config = V4l2Config::new(&path);
        config.format = format;
        config.exposure_s = f64::from(camera.response.exposure_s);
        config.gain = options.gain;
        config.white_balance_k = options.white_balance_k;
        V4l2Camera::open(config, camera.device.clone(), camera.response.clone())
            .map_err(|e| e.to_string())
    };
    Ok(super::CaptureHost::new(CameraNode::lazy(
        name,
        Box::new(open),
    )))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::TimedFrame;
    use crate::camera::recorded::Recorder;
    use crate::node::CaptureDevices;
    use showcase_light::Image;
    use showcase_proto::{CameraResponse, PinholeDevice};

    fn device(w: u32, h: u32) -> PinholeDevice {
        PinholeDevice::look_at(
            glam::DVec3::ZERO,
            glam::DVec3::Z,
            glam::DVec3::NEG_Y,
            60.0,
            w,
            h,
        )
    }

    /// A scene whose one camera, `camera-0`, is `w x h`.
    fn scene_with_camera(w: u32, h: u32) -> Arc<Showcase> {
        Arc::new(Showcase {
            cameras: vec![Camera {
                name: "camera-0".into(),
                device: device(w, h),
                response: CameraResponse::default(),
            }],
            ..Showcase::default()
        })
    }

    /// One frame at 1/30 s and unit gain.
    const ONE_FRAME: CaptureFrames = CaptureFrames {
        id: 1,
        exposure_s: 1.0 / 30.0,
        gain: 1.0,
        period_s: 0.0,
        count: 1,
    };

    /// A recording in `dir` of `frames` frames of a `w x h` camera.
    fn record(dir: &std::path::Path, w: u32, h: u32, frames: u32) {
        let mut rec = Recorder::create(dir, device(w, h), CameraResponse::default()).unwrap();
        for k in 0..frames {
            rec.push(&TimedFrame {
                frame: CameraFrame {
                    codes: Image::from_fn(w, h, |x, _| [x as u16 * 20; 3]),
                    bits: 8,
                },
                timestamp_s: f64::from(k) / 30.0,
                start_of_exposure: false,
                sequence: k,
                exposure_s: 1.0 / 30.0,
            })
            .unwrap();
        }
        rec.finish().unwrap();
    }

    #[test]
    fn specs_parse_and_bad_ones_say_the_form() {
        assert_eq!(
            "v4l2:/dev/video2:640x480:YUYV".parse(),
            Ok(CameraSpec::V4l2 {
                path: "/dev/video2".into(),
                size: Some((640, 480)),
                format: Some("YUYV".into())
            })
        );
        assert_eq!(
            "v4l2:/dev/video0".parse(),
            Ok(CameraSpec::V4l2 {
                path: "/dev/video0".into(),
                size: None,
                format: None
            })
        );
        assert_eq!(
            "recorded:cam/white".parse(),
            Ok(CameraSpec::Recorded("cam/white".into()))
        );
        for bad in ["usb:0", "v4l2:", "v4l2:/dev/video0:640", "recorded:"] {
            let e = bad.parse::<CameraSpec>().unwrap_err();
            assert!(
                e.contains("v4l2:/dev/videoN") || e.contains("WIDTHxHEIGHT"),
                "{e}"
            );
        }
    }

    #[cfg(not(all(feature = "v4l2", target_os = "linux")))]
    #[test]
    fn without_the_feature_v4l2_says_how_to_build() {
        let spec = "v4l2:/dev/video0".parse().unwrap();
        let e = camera_node("camera-0", &spec, V4l2NodeOptions::default()).unwrap_err();
        assert!(e.contains("--features v4l2"), "{e}");
    }

    /// A V4L2 node asked for another size than the scene's camera says
    /// which `--camera` to give, before it opens the device.
    #[cfg(all(feature = "v4l2", target_os = "linux"))]
    #[test]
    fn a_v4l2_node_of_another_size_says_which_spec_to_give() {
        let spec = "v4l2:/dev/showcase-no-such-camera:16x12".parse().unwrap();
        let host = camera_node("camera-0", &spec, V4l2NodeOptions::default()).unwrap();
        let mut devices = host.0.lock().unwrap();
        devices.set_scene(scene_with_camera(8, 6));
        let request = CaptureFrames {
            exposure_s: 0.02,
            ..ONE_FRAME
        };
        let e = devices.capture(&request).unwrap_err();
        assert!(
            e.contains("--camera v4l2:/dev/showcase-no-such-camera:8x6"),
            "{e}"
        );
    }

    /// A lazily opened camera follows the scene's camera: the same camera
    /// keeps it open, another size or calibration closes it and opens it
    /// again for that camera.
    #[test]
    fn a_lazy_camera_is_opened_again_when_the_scenes_camera_changes() {
        let root =
            std::env::temp_dir().join(format!("showcase-camnode-reopen-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        for (w, h) in [(8, 6), (16, 12)] {
            // One frame for each capture the camera serves while open.
            record(&root.join(format!("{w}x{h}")), w, h, 2);
        }
        let opened = Arc::new(std::sync::Mutex::new(Vec::new()));
        let (dir, log) = (root.clone(), opened.clone());
        let mut node = CameraNode::lazy(
            "camera-0",
            Box::new(move |c: &Camera| {
                let (w, h) = (c.device.width, c.device.height);
                log.lock().unwrap().push((w, h));
                RecordedCamera::open(dir.join(format!("{w}x{h}"))).map_err(|e| e.to_string())
            }),
        );
        let size = |f: &[CameraFrame]| (f[0].codes.width, f[0].codes.height);
        node.set_scene(scene_with_camera(8, 6));
        assert_eq!(size(&node.capture(&ONE_FRAME).unwrap()), (8, 6));
        node.set_scene(scene_with_camera(8, 6));
        assert_eq!(size(&node.capture(&ONE_FRAME).unwrap()), (8, 6));
        assert_eq!(
            *opened.lock().unwrap(),
            [(8, 6)],
            "the same camera was opened again"
        );
        node.set_scene(scene_with_camera(16, 12));
        assert_eq!(size(&node.capture(&ONE_FRAME).unwrap()), (16, 12));
        assert_eq!(*opened.lock().unwrap(), [(8, 6), (16, 12)]);
        std::fs::remove_dir_all(&root).ok();
    }

    /// A recorded camera of another size than the scene's camera, or asked
    /// another gain than it was recorded with: the
    /// capture says both sizes and what to change.
    #[test]
    fn a_camera_of_another_size_or_gain_says_what_to_change() {
        let dir =
            std::env::temp_dir().join(format!("showcase-camnode-size-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        record(&dir, 8, 6, 1);
        let node = |w, h| {
            let mut n = CameraNode::new("camera-0", RecordedCamera::open(&dir).unwrap());
            n.set_scene(scene_with_camera(w, h));
            n
        };
        let request = ONE_FRAME;
        let e = node(16, 12).capture(&request).unwrap_err();
        assert!(
            e.contains("delivers 8x6 frames") && e.contains("is 16x12") && e.contains("record"),
            "{e}"
        );
        let other_gain = CaptureFrames {
            gain: 2.0,
            ..request
        };
        let e = node(8, 6).capture(&other_gain).unwrap_err();
        assert!(e.contains("a recording cannot change its gain"), "{e}");
        assert_eq!(node(8, 6).capture(&request).unwrap().len(), 1);
        std::fs::remove_dir_all(&dir).ok();
    }
}
