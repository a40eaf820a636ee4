//! The Video4Linux2 backend (Linux, cargo feature `v4l2`): a UVC or other
//! V4L2 camera through raw ioctls (no system library, no build-time
//! dependency) with memory-mapped streaming.
//!
//! Opening a camera enumerates its formats and sizes, [`negotiate`]s one
//! (the calibrated size, exactly), sets it and checks the driver kept it,
//! then switches every automatic control off: exposure to manual with the
//! asked time (`EXPOSURE_ABSOLUTE`, 100 µs units), auto gain and auto white
//! balance off, the gain to the asked value. A control the camera lacks or
//! refuses stops the opening with a message naming it.
//!
//! [`V4l2Camera::capture_timed`] returns a frame whose exposure began after
//! the call, known from the buffer's timestamp (`CLOCK_MONOTONIC`), so a
//! frame still queued from before the projector changed its image is never
//! used; [`CameraDevice::capture`] also stops on a saturated frame.
//!
//! Only the few ioctls and structures needed are declared here, as the
//! kernel's `videodev2.h` lays them out; the layouts are tested against the
//! kernel's ioctl numbers.
#![allow(unsafe_code)]

use super::decode::{self, DecodeError, FrameLayout, PixelFormat, fourcc_string};
use super::{
    FormatChoice, FormatRequest, FrameSizes, LevelError, LevelLimits, NegotiationError,
    OfferedFormat, Settings, TimedFrame, check_applied, check_saturation, negotiate,
};
use showcase_light::hardware::{CameraDevice, CameraFrame};
use showcase_proto::{CameraResponse, PinholeDevice};
use std::ffi::CString;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::os::unix::ffi::OsStrExt;
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------
// videodev2.h: the structures and ioctl numbers used.

const BUF_TYPE_VIDEO_CAPTURE: u32 = 1;
const MEMORY_MMAP: u32 = 1;
const FIELD_NONE: u32 = 1;
const CAP_VIDEO_CAPTURE: u32 = 0x0000_0001;
const CAP_STREAMING: u32 = 0x0400_0000;
const CAP_DEVICE_CAPS: u32 = 0x8000_0000;
const CAP_TIMEPERFRAME: u32 = 0x1000;
const FRMSIZE_TYPE_DISCRETE: u32 = 1;
const QUANTIZATION_FULL_RANGE: u32 = 1;
const BUF_FLAG_ERROR: u32 = 0x0040;
const BUF_FLAG_TIMESTAMP_MASK: u32 = 0xe000;
const BUF_FLAG_TIMESTAMP_MONOTONIC: u32 = 0x2000;
const BUF_FLAG_TSTAMP_SRC_MASK: u32 = 0x0007_0000;
const BUF_FLAG_TSTAMP_SRC_SOE: u32 = 0x0001_0000;
const CTRL_FLAG_DISABLED: u32 = 0x0001;

const CID_BASE: u32 = 0x0098_0900;
/// `V4L2_CID_AUTO_WHITE_BALANCE`.
const CID_AUTO_WHITE_BALANCE: u32 = CID_BASE + 12;
/// `V4L2_CID_AUTOGAIN`.
const CID_AUTOGAIN: u32 = CID_BASE + 18;
/// `V4L2_CID_GAIN`.
const CID_GAIN: u32 = CID_BASE + 19;
/// `V4L2_CID_WHITE_BALANCE_TEMPERATURE`.
const CID_WHITE_BALANCE_TEMPERATURE: u32 = CID_BASE + 26;
const CID_CAMERA_CLASS_BASE: u32 = 0x009a_0900;
/// `V4L2_CID_EXPOSURE_AUTO` (a menu; 1 is `V4L2_EXPOSURE_MANUAL`).
const CID_EXPOSURE_AUTO: u32 = CID_CAMERA_CLASS_BASE + 1;
const EXPOSURE_MANUAL: i32 = 1;
/// `V4L2_CID_EXPOSURE_ABSOLUTE`, in units of 100 µs.
const CID_EXPOSURE_ABSOLUTE: u32 = CID_CAMERA_CLASS_BASE + 2;
/// `V4L2_CID_EXPOSURE_AUTO_PRIORITY` (0: keep the frame rate).
const CID_EXPOSURE_AUTO_PRIORITY: u32 = CID_CAMERA_CLASS_BASE + 3;

#[repr(C)]
#[derive(Clone, Copy)]
struct Capability {
    driver: [u8; 16],
    card: [u8; 32],
    bus_info: [u8; 32],
    version: u32,
    capabilities: u32,
    device_caps: u32,
    reserved: [u32; 3],
}

#[repr(C)]
#[derive(Clone, Copy)]
struct FmtDesc {
    index: u32,
    type_: u32,
    flags: u32,
    description: [u8; 32],
    pixelformat: u32,
    mbus_code: u32,
    reserved: [u32; 3],
}

#[repr(C)]
#[derive(Clone, Copy)]
struct FrmSizeEnum {
    index: u32,
    pixel_format: u32,
    type_: u32,
    /// Discrete: width, height; stepwise: min, max, step of the width,
    /// then of the height.
    size: [u32; 6],
    reserved: [u32; 2],
}

#[repr(C)]
#[derive(Clone, Copy)]
struct PixFormat {
    width: u32,
    height: u32,
    pixelformat: u32,
    field: u32,
    bytesperline: u32,
    sizeimage: u32,
    colorspace: u32,
    priv_: u32,
    flags: u32,
    ycbcr_enc: u32,
    quantization: u32,
    xfer_func: u32,
}

/// `struct v4l2_format`: its union holds pointers (`v4l2_window`), hence
/// the pointer alignment.
#[repr(C)]
#[derive(Clone, Copy)]
struct Format {
    type_: u32,
    fmt: FormatUnion,
}

/// The union of `struct v4l2_format`, of which only `pix` is used.
#[repr(C)]
#[derive(Clone, Copy)]
struct FormatUnion {
    pix: PixFormat,
    rest: [u8; 200 - size_of::<PixFormat>()],
    _align: [usize; 0],
}

#[repr(C)]
#[derive(Clone, Copy)]
struct StreamParm {
    type_: u32,
    capability: u32,
    capturemode: u32,
    timeperframe: [u32; 2],
    extendedmode: u32,
    readbuffers: u32,
    reserved: [u32; 4],
    rest: [u8; 200 - 40],
}

#[repr(C)]
#[derive(Clone, Copy)]
struct RequestBuffers {
    count: u32,
    type_: u32,
    memory: u32,
    capabilities: u32,
    flags: u8,
    reserved: [u8; 3],
}

#[repr(C)]
#[derive(Clone, Copy)]
struct Timecode {
    type_: u32,
    flags: u32,
    frames: u8,
    seconds: u8,
    minutes: u8,
    hours: u8,
    userbits: [u8; 4],
}

#[repr(C)]
#[derive(Clone, Copy)]
union BufferM {
    offset: u32,
    userptr: libc::c_ulong,
}

#[repr(C)]
#[derive(Clone, Copy)]
struct Buffer {
    index: u32,
    type_: u32,
    bytesused: u32,
    flags: u32,
    field: u32,
    timestamp: libc::timeval,
    timecode: Timecode,
    sequence: u32,
    memory: u32,
    m: BufferM,
    length: u32,
    reserved2: u32,
    request_fd: i32,
}

#[repr(C)]
#[derive(Clone, Copy)]
struct Control {
    id: u32,
    value: i32,
}

#[repr(C)]
#[derive(Clone, Copy)]
struct QueryCtrl {
    id: u32,
    type_: u32,
    name: [u8; 32],
    minimum: i32,
    maximum: i32,
    step: i32,
    default_value: i32,
    flags: u32,
    reserved: [u32; 2],
}

const IOC_WRITE: u32 = 1;
const IOC_READ: u32 = 2;

/// `_IOC(dir, 'V', nr, size)`.
const fn ioc(dir: u32, nr: u32, size: usize) -> u32 {
    (dir << 30) | ((size as u32) << 16) | ((b'V' as u32) << 8) | nr
}

const VIDIOC_QUERYCAP: u32 = ioc(IOC_READ, 0, size_of::<Capability>());
const VIDIOC_ENUM_FMT: u32 = ioc(IOC_READ | IOC_WRITE, 2, size_of::<FmtDesc>());
const VIDIOC_S_FMT: u32 = ioc(IOC_READ | IOC_WRITE, 5, size_of::<Format>());
const VIDIOC_REQBUFS: u32 = ioc(IOC_READ | IOC_WRITE, 8, size_of::<RequestBuffers>());
const VIDIOC_QUERYBUF: u32 = ioc(IOC_READ | IOC_WRITE, 9, size_of::<Buffer>());
const VIDIOC_QBUF: u32 = ioc(IOC_READ | IOC_WRITE, 15, size_of::<Buffer>());
const VIDIOC_DQBUF: u32 = ioc(IOC_READ | IOC_WRITE, 17, size_of::<Buffer>());
const VIDIOC_STREAMON: u32 = ioc(IOC_WRITE, 18, size_of::<libc::c_int>());
const VIDIOC_STREAMOFF: u32 = ioc(IOC_WRITE, 19, size_of::<libc::c_int>());
const VIDIOC_G_PARM: u32 = ioc(IOC_READ | IOC_WRITE, 21, size_of::<StreamParm>());
const VIDIOC_S_PARM: u32 = ioc(IOC_READ | IOC_WRITE, 22, size_of::<StreamParm>());
const VIDIOC_G_CTRL: u32 = ioc(IOC_READ | IOC_WRITE, 27, size_of::<Control>());
const VIDIOC_S_CTRL: u32 = ioc(IOC_READ | IOC_WRITE, 28, size_of::<Control>());
const VIDIOC_QUERYCTRL: u32 = ioc(IOC_READ | IOC_WRITE, 36, size_of::<QueryCtrl>());
const VIDIOC_ENUM_FRAMESIZES: u32 = ioc(IOC_READ | IOC_WRITE, 74, size_of::<FrmSizeEnum>());

/// A zeroed videodev2 structure.
fn zeroed<T: Copy>() -> T {
    // SAFETY: only used for the plain-data repr(C) structures above
    // (integers, byte arrays, a timeval and a union of integers), for
    // which all-zero bytes are a valid value, as the kernel API expects.
    unsafe { std::mem::zeroed() }
}

/// One ioctl on `fd`, retried on EINTR.
fn xioctl<T>(fd: &OwnedFd, request: u32, arg: &mut T) -> io::Result<()> {
    loop {
        // SAFETY: `request` is one of the VIDIOC numbers above, each
        // encoding the size of the structure `T` it is called with (see
        // `ioctl_numbers_match_the_kernel`); `arg` is a valid, exclusive
        // pointer to such a structure for the duration of the call.
        let r = unsafe {
            libc::ioctl(
                fd.as_raw_fd(),
                request as libc::Ioctl,
                arg as *mut T as *mut libc::c_void,
            )
        };
        if r != -1 {
            return Ok(());
        }
        let e = io::Error::last_os_error();
        if e.kind() != io::ErrorKind::Interrupted {
            return Err(e);
        }
    }
}

fn c_text(bytes: &[u8]) -> String {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..end]).trim().to_string()
}

/// `CLOCK_MONOTONIC` now, in seconds (the clock of V4L2 timestamps).
pub fn monotonic_now_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid timespec to write; CLOCK_MONOTONIC always
    // exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

// ---------------------------------------------------------------------------
// Errors.

/// Why the camera cannot be used; each message says what to change.
#[derive(Debug, thiserror::Error)]
pub enum V4l2Error {
    /// The device file cannot be opened.
    #[error(
        "{path}: cannot open the camera ({error}); check the path (`ls /dev/video*`), that the \
         camera is plugged in and not used by another program, and that this user may read it \
         (group `video`)"
    )]
    Open {
        /// Device path.
        path: PathBuf,
        /// The error.
        error: io::Error,
    },
    /// An ioctl failed.
    #[error("{path}: {what} failed: {error}")]
    Ioctl {
        /// Device path.
        path: PathBuf,
        /// What was being done.
        what: String,
        /// The error.
        error: io::Error,
    },
    /// The device does not stream video frames.
    #[error(
        "{path} ('{card}') is not a streaming video capture device; a UVC camera has several \
         /dev/videoN nodes (one only carries metadata): try the next one (`v4l2-ctl \
         --list-devices` lists them)"
    )]
    NotCapture {
        /// Device path.
        path: PathBuf,
        /// The driver's name for the card.
        card: String,
    },
    /// No format fits the request.
    #[error("{path}: {error}")]
    Format {
        /// Device path.
        path: PathBuf,
        /// Why.
        error: NegotiationError,
    },
    /// A manual control the capture needs is missing.
    #[error("{path}: the camera has no {control} control; {hint}")]
    NoControl {
        /// Device path.
        path: PathBuf,
        /// The control's name.
        control: &'static str,
        /// What to do.
        hint: &'static str,
    },
    /// A control's value is outside its range.
    #[error(
        "{path}: {control} {value} is outside the camera's range {min} to {max} (step {step}); \
         choose a value in it"
    )]
    OutOfRange {
        /// Device path.
        path: PathBuf,
        /// The control's name, with its unit.
        control: &'static str,
        /// Asked value, in the control's unit.
        value: i64,
        /// Smallest value.
        min: i64,
        /// Largest value.
        max: i64,
        /// Step.
        step: i64,
    },
    /// The camera did not keep a control's value.
    #[error(
        "{path}: set {control} to {asked}, the camera reports {got}; another program (or the \
         camera's own automatic mode) may be changing it: close it and try again"
    )]
    ControlNotKept {
        /// Device path.
        path: PathBuf,
        /// The control's name.
        control: &'static str,
        /// Asked value.
        asked: i32,
        /// Value read back.
        got: i32,
    },
    /// No frame came in time.
    #[error(
        "{path}: no usable frame in {seconds:.1} s ({errors} corrupt); check the USB connection \
         (a USB 3 port, no passive hub), lower the frame size or use MJPEG, and that the exposure \
         ({exposure_ms:.1} ms) fits the frame rate"
    )]
    Timeout {
        /// Device path.
        path: PathBuf,
        /// Time waited.
        seconds: f64,
        /// Frames the driver marked corrupt meanwhile.
        errors: u32,
        /// The exposure in use.
        exposure_ms: f64,
    },
    /// A frame could not be decoded.
    #[error("{path}: {error}")]
    Decode {
        /// Device path.
        path: PathBuf,
        /// Why.
        error: DecodeError,
    },
    /// A frame is saturated.
    #[error("{path}: {error}")]
    Levels {
        /// Device path.
        path: PathBuf,
        /// Why.
        error: LevelError,
    },
}

// ---------------------------------------------------------------------------
// Listing.

/// A control the camera offers.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ControlInfo {
    /// The control id (`V4L2_CID_*`).
    pub id: u32,
    /// The driver's name.
    pub name: String,
    /// Smallest value.
    pub min: i32,
    /// Largest value.
    pub max: i32,
    /// Step.
    pub step: i32,
    /// Default value.
    pub default: i32,
    /// Current value, when readable.
    pub value: Option<i32>,
}

/// What a camera is and offers.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceInfo {
    /// Device path.
    pub path: PathBuf,
    /// Driver name (`uvcvideo`).
    pub driver: String,
    /// The camera's name.
    pub card: String,
    /// Where it is plugged.
    pub bus: String,
    /// Formats and sizes it offers.
    pub formats: Vec<OfferedFormat>,
    /// The exposure, gain and white-balance controls it offers.
    pub controls: Vec<ControlInfo>,
}

/// The controls [`list`] reports.
const LISTED_CONTROLS: [u32; 7] = [
    CID_EXPOSURE_AUTO,
    CID_EXPOSURE_ABSOLUTE,
    CID_EXPOSURE_AUTO_PRIORITY,
    CID_AUTOGAIN,
    CID_GAIN,
    CID_AUTO_WHITE_BALANCE,
    CID_WHITE_BALANCE_TEMPERATURE,
];

/// Lists what the camera at `path` offers, changing nothing.
pub fn list(path: impl AsRef<Path>) -> Result<DeviceInfo, V4l2Error> {
    let dev = Device::open(path.as_ref())?;
    let cap = dev.capability()?;
    let formats = dev.formats()?;
    let mut controls = Vec::new();
    for id in LISTED_CONTROLS {
        if let Some(q) = dev.query_control(id)? {
            controls.push(ControlInfo {
                id,
                name: c_text(&q.name),
                min: q.minimum,
                max: q.maximum,
                step: q.step,
                default: q.default_value,
                value: dev.get_control(id).ok(),
            });
        }
    }
    Ok(DeviceInfo {
        path: dev.path.clone(),
        driver: c_text(&cap.driver),
        card: c_text(&cap.card),
        bus: c_text(&cap.bus_info),
        formats,
        controls,
    })
}

// ---------------------------------------------------------------------------
// The device.

/// An open device node.
struct Device {
    fd: OwnedFd,
    path: PathBuf,
}

impl Device {
    fn open(path: &Path) -> Result<Self, V4l2Error> {
        let open_error = |source| V4l2Error::Open {
            path: path.to_path_buf(),
            error: source,
        };
        let c_path = CString::new(path.as_os_str().as_bytes())
            .map_err(|e| open_error(io::Error::new(io::ErrorKind::InvalidInput, e)))?;
        // SAFETY: `c_path` is a valid NUL-terminated string; the returned
        // descriptor is owned by nothing else.
        let raw = unsafe {
            libc::open(
                c_path.as_ptr(),
                libc::O_RDWR | libc::O_NONBLOCK | libc::O_CLOEXEC,
            )
        };
        if raw < 0 {
            return Err(open_error(io::Error::last_os_error()));
        }
        // SAFETY: `raw` is a freshly opened descriptor that we own.
        let fd = unsafe { OwnedFd::from_raw_fd(raw) };
        Ok(Self {
            fd,
            path: path.to_path_buf(),
        })
    }

    fn ioctl<T>(&self, request: u32, what: &str, arg: &mut T) -> Result<(), V4l2Error> {
        xioctl(&self.fd, request, arg).map_err(|error| {
            let hint = match error.raw_os_error() {
                Some(libc::EBUSY) => " (another program is streaming from the camera: close it)",
                Some(libc::ENODEV) => " (the camera was unplugged)",
                _ => "",
            };
            V4l2Error::Ioctl {
                path: self.path.clone(),
                what: format!("{what}{hint}"),
                error,
            }
        })
    }

    fn capability(&self) -> Result<Capability, V4l2Error> {
        let mut cap: Capability = zeroed();
        match xioctl(&self.fd, VIDIOC_QUERYCAP, &mut cap) {
            Ok(()) => {}
            Err(e) if e.raw_os_error() == Some(libc::ENOTTY) => {
                return Err(V4l2Error::NotCapture {
                    path: self.path.clone(),
                    card: "not a V4L2 device".into(),
                });
            }
            Err(error) => {
                return Err(V4l2Error::Ioctl {
                    path: self.path.clone(),
                    what: "VIDIOC_QUERYCAP".into(),
                    error,
                });
            }
        }
        let caps = if cap.capabilities & CAP_DEVICE_CAPS != 0 {
            cap.device_caps
        } else {
            cap.capabilities
        };
        if caps & CAP_VIDEO_CAPTURE == 0 || caps & CAP_STREAMING == 0 {
            return Err(V4l2Error::NotCapture {
                path: self.path.clone(),
                card: c_text(&cap.card),
            });
        }
        Ok(cap)
    }

    /// Every capture format with its sizes (an EINVAL ends each list).
    fn formats(&self) -> Result<Vec<OfferedFormat>, V4l2Error> {
        let mut out = Vec::new();
        for index in 0..256 {
            let mut desc: FmtDesc = zeroed();
            desc.index = index;
            desc.type_ = BUF_TYPE_VIDEO_CAPTURE;
            match xioctl(&self.fd, VIDIOC_ENUM_FMT, &mut desc) {
                Ok(()) => {}
                Err(e) if e.raw_os_error() == Some(libc::EINVAL) => break,
                Err(source) => {
                    return Err(V4l2Error::Ioctl {
                        path: self.path.clone(),
                        what: "VIDIOC_ENUM_FMT".into(),
                        error: source,
                    });
                }
            }
            out.push(OfferedFormat {
                fourcc: desc.pixelformat,
                description: c_text(&desc.description),
                sizes: self.sizes(desc.pixelformat)?,
            });
        }
        Ok(out)
    }

    fn sizes(&self, fourcc: u32) -> Result<FrameSizes, V4l2Error> {
        let mut discrete = Vec::new();
        for index in 0..1024 {
            let mut size: FrmSizeEnum = zeroed();
            size.index = index;
            size.pixel_format = fourcc;
            match xioctl(&self.fd, VIDIOC_ENUM_FRAMESIZES, &mut size) {
                Ok(()) => {}
                Err(e) if e.raw_os_error() == Some(libc::EINVAL) => break,
                Err(source) => {
                    return Err(V4l2Error::Ioctl {
                        path: self.path.clone(),
                        what: format!("VIDIOC_ENUM_FRAMESIZES ({})", fourcc_string(fourcc)),
                        error: source,
                    });
                }
            }
            let s = size.size;
            if size.type_ == FRMSIZE_TYPE_DISCRETE {
                discrete.push((s[0], s[1]));
            } else {
                // Continuous (step 1) or stepwise: one entry describes all.
                return Ok(FrameSizes::Stepwise {
                    min: (s[0], s[3]),
                    max: (s[1], s[4]),
                    step: (s[2], s[5]),
                });
            }
        }
        Ok(FrameSizes::Discrete(discrete))
    }

    /// The control's description, or `None` when the camera lacks it (or
    /// has it disabled).
    fn query_control(&self, id: u32) -> Result<Option<QueryCtrl>, V4l2Error> {
        let mut q: QueryCtrl = zeroed();
        q.id = id;
        match xioctl(&self.fd, VIDIOC_QUERYCTRL, &mut q) {
            Ok(()) if q.flags & CTRL_FLAG_DISABLED == 0 => Ok(Some(q)),
            Ok(()) => Ok(None),
            Err(e) if e.raw_os_error() == Some(libc::EINVAL) => Ok(None),
            Err(source) => Err(V4l2Error::Ioctl {
                path: self.path.clone(),
                what: format!("VIDIOC_QUERYCTRL (0x{id:08x})"),
                error: source,
            }),
        }
    }

    fn get_control(&self, id: u32) -> io::Result<i32> {
        let mut c = Control { id, value: 0 };
        xioctl(&self.fd, VIDIOC_G_CTRL, &mut c)?;
        Ok(c.value)
    }

    /// Sets a control and checks the camera kept the value.
    fn set_control(&self, id: u32, name: &'static str, value: i32) -> Result<(), V4l2Error> {
        let mut c = Control { id, value };
        self.ioctl(VIDIOC_S_CTRL, &format!("setting {name} to {value}"), &mut c)?;
        match self.get_control(id) {
            Ok(got) if got != value => Err(V4l2Error::ControlNotKept {
                path: self.path.clone(),
                control: name,
                asked: value,
                got,
            }),
            // Some controls are write-only: trust the set.
            _ => Ok(()),
        }
    }

    /// Sets a control that must exist, after checking its range.
    fn set_ranged(
        &self,
        id: u32,
        name: &'static str,
        value: i64,
        hint: &'static str,
    ) -> Result<i32, V4l2Error> {
        let q = self.query_control(id)?.ok_or(V4l2Error::NoControl {
            path: self.path.clone(),
            control: name,
            hint,
        })?;
        let (min, max, step) = (
            i64::from(q.minimum),
            i64::from(q.maximum),
            i64::from(q.step.max(1)),
        );
        if value < min || value > max || (value - min) % step != 0 {
            return Err(V4l2Error::OutOfRange {
                path: self.path.clone(),
                control: name,
                value,
                min,
                max,
                step,
            });
        }
        let value = value as i32;
        self.set_control(id, name, value)?;
        Ok(value)
    }

    /// Turns an automatic control off when the camera has one.
    fn switch_off(&self, id: u32, name: &'static str, off: i32) -> Result<(), V4l2Error> {
        if self.query_control(id)?.is_some() {
            self.set_control(id, name, off)?;
        }
        Ok(())
    }
}

/// One memory-mapped buffer.
struct Mapping {
    ptr: *mut libc::c_void,
    len: usize,
}

// SAFETY: the mapping is plain shared memory owned by this value alone;
// nothing in it is tied to the thread that mapped it.
unsafe impl Send for Mapping {}

impl Drop for Mapping {
    fn drop(&mut self) {
        // SAFETY: `ptr` and `len` are those mmap returned, unmapped once.
        unsafe { libc::munmap(self.ptr, self.len) };
    }
}

/// How to open a camera.
#[derive(Clone, Debug, PartialEq)]
pub struct V4l2Config {
    /// The device node (`/dev/video0`).
    pub path: PathBuf,
    /// The pixel format, or `None` to let [`negotiate`] choose.
    pub format: Option<PixelFormat>,
    /// Exposure time in seconds (manual; the camera's unit is 100 µs).
    pub exposure_s: f64,
    /// The gain control's value, or `None` to leave it as it is (auto gain
    /// is switched off either way).
    pub gain: Option<i32>,
    /// A fixed white-balance temperature in kelvin, or `None` to leave it
    /// (auto white balance is switched off either way).
    pub white_balance_k: Option<i32>,
    /// Frames per second to ask for, or `None` for the driver's.
    pub fps: Option<f64>,
    /// Buffers to stream through (at least 2).
    pub buffers: u32,
    /// How long to wait for a usable frame.
    pub timeout_s: f64,
    /// A frame counts only when its exposure began this long after the
    /// capture was asked for: the projector's own latency in showing the
    /// image it was just given.
    pub settle_s: f64,
    /// Saturation check on every capture; `None` for none.
    pub limits: Option<LevelLimits>,
}

impl V4l2Config {
    /// The defaults for `path`: any format, 1/30 s exposure, gain and
    /// white balance as they are (automatics off), 4 buffers, 5 s timeout,
    /// 50 ms for the projector to settle, the default saturation check.
    pub fn new(path: impl Into<PathBuf>) -> Self {
        Self {
            path: path.into(),
            format: None,
            exposure_s: 1.0 / 30.0,
            gain: None,
            white_balance_k: None,
            fps: None,
            buffers: 4,
            timeout_s: 5.0,
            settle_s: 0.05,
            limits: Some(LevelLimits::default()),
        }
    }
}

/// A frame's bytes as the driver handed them over.
struct Dequeued {
    bytes: Vec<u8>,
    /// `timeval` in seconds.
    timestamp_s: f64,
    /// `V4L2_BUF_FLAG_*`.
    flags: u32,
    sequence: u32,
}

/// A streaming V4L2 camera with manual exposure and gain.
pub struct V4l2Camera {
    dev: Device,
    buffers: Vec<Mapping>,
    choice: FormatChoice,
    layout: FrameLayout,
    device: PinholeDevice,
    response: CameraResponse,
    config: V4l2Config,
    /// Exposure now set, in 100 µs units.
    exposure_units: i32,
    gain: Option<i32>,
    frame_period_s: f64,
}

impl std::fmt::Debug for V4l2Camera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("V4l2Camera")
            .field("path", &self.dev.path)
            .field("format", &self.choice)
            .field("exposure_s", &self.exposure_s())
            .field("gain", &self.gain)
            .finish_non_exhaustive()
    }
}

/// Exposure seconds to the camera's 100 µs units.
fn exposure_units(exposure_s: f64) -> i64 {
    if exposure_s.is_finite() {
        (exposure_s * 1e4).round() as i64
    } else {
        -1
    }
}

impl V4l2Camera {
    /// Opens the camera of `config` at the size of `device` (the
    /// calibrated geometry) and starts streaming with manual exposure and
    /// gain; `response` is its photometric calibration.
    pub fn open(
        config: V4l2Config,
        device: PinholeDevice,
        response: CameraResponse,
    ) -> Result<Self, V4l2Error> {
        let dev = Device::open(&config.path)?;
        dev.capability()?;
        let offered = dev.formats()?;
        let request = FormatRequest {
            format: config.format,
            width: device.width,
            height: device.height,
        };
        let format_error = |source| V4l2Error::Format {
            path: config.path.clone(),
            error: source,
        };
        let choice = negotiate(&offered, &request).map_err(format_error)?;

        let mut fmt: Format = zeroed();
        fmt.type_ = BUF_TYPE_VIDEO_CAPTURE;
        fmt.fmt.pix.width = choice.width;
        fmt.fmt.pix.height = choice.height;
        fmt.fmt.pix.pixelformat = choice.format.fourcc();
        fmt.fmt.pix.field = FIELD_NONE;
        dev.ioctl(VIDIOC_S_FMT, &format!("setting {choice}"), &mut fmt)?;
        check_applied(
            &choice,
            fmt.fmt.pix.pixelformat,
            fmt.fmt.pix.width,
            fmt.fmt.pix.height,
        )
        .map_err(format_error)?;
        let layout = FrameLayout {
            format: choice.format,
            width: choice.width,
            height: choice.height,
            bytes_per_line: fmt.fmt.pix.bytesperline,
            full_range: fmt.fmt.pix.quantization == QUANTIZATION_FULL_RANGE,
        };

        let frame_period_s = Self::frame_rate(&dev, config.fps)?;

        // Every automatic off before the manual values go in (UVC cameras
        // refuse a manual exposure while auto exposure is on).
        const NO_EXPOSURE: &str = "the capture needs a camera with manual exposure (UVC: \
                                   `exposure_time_absolute`)";
        if dev.query_control(CID_EXPOSURE_AUTO)?.is_some() {
            dev.set_control(
                CID_EXPOSURE_AUTO,
                "auto exposure (manual mode)",
                EXPOSURE_MANUAL,
            )?;
        }
        // Only a nicety (a steady frame rate): some cameras refuse it.
        let _ = dev.switch_off(CID_EXPOSURE_AUTO_PRIORITY, "exposure auto priority", 0);
        dev.switch_off(CID_AUTOGAIN, "auto gain", 0)?;
        dev.switch_off(CID_AUTO_WHITE_BALANCE, "auto white balance", 0)?;
        let exposure_units = dev.set_ranged(
            CID_EXPOSURE_ABSOLUTE,
            "exposure (100 µs units)",
            exposure_units(config.exposure_s),
            NO_EXPOSURE,
        )?;
        let gain = match config.gain {
            Some(g) => Some(dev.set_ranged(
                CID_GAIN,
                "gain",
                i64::from(g),
                "leave the gain unset, or use a camera with a gain control",
            )?),
            None => dev.get_control(CID_GAIN).ok(),
        };
        if let Some(k) = config.white_balance_k {
            dev.set_ranged(
                CID_WHITE_BALANCE_TEMPERATURE,
                "white balance temperature (K)",
                i64::from(k),
                "leave the white balance unset",
            )?;
        }

        let buffers = Self::start(&dev, config.buffers.max(2))?;
        Ok(Self {
            dev,
            buffers,
            choice,
            layout,
            device,
            response,
            config,
            exposure_units,
            gain,
            frame_period_s,
        })
    }

    /// Asks for `fps` when given and returns the frame period in force.
    fn frame_rate(dev: &Device, fps: Option<f64>) -> Result<f64, V4l2Error> {
        let mut parm: StreamParm = zeroed();
        parm.type_ = BUF_TYPE_VIDEO_CAPTURE;
        if xioctl(&dev.fd, VIDIOC_G_PARM, &mut parm).is_err() {
            // A driver without frame-rate control: assume video rate.
            return Ok(1.0 / 30.0);
        }
        if let Some(fps) = fps.filter(|f| f.is_finite() && *f > 0.0)
            && parm.capability & CAP_TIMEPERFRAME != 0
        {
            parm.timeperframe = [1000, (fps * 1000.0).round() as u32];
            dev.ioctl(VIDIOC_S_PARM, &format!("setting {fps} frames/s"), &mut parm)?;
        }
        let [num, den] = parm.timeperframe;
        Ok(if num > 0 && den > 0 {
            f64::from(num) / f64::from(den)
        } else {
            1.0 / 30.0
        })
    }

    /// Maps `count` buffers, queues them and starts streaming.
    fn start(dev: &Device, count: u32) -> Result<Vec<Mapping>, V4l2Error> {
        let mut req: RequestBuffers = zeroed();
        req.count = count;
        req.type_ = BUF_TYPE_VIDEO_CAPTURE;
        req.memory = MEMORY_MMAP;
        dev.ioctl(VIDIOC_REQBUFS, "VIDIOC_REQBUFS", &mut req)?;
        if req.count < 2 {
            return Err(V4l2Error::Ioctl {
                path: dev.path.clone(),
                what: "VIDIOC_REQBUFS".into(),
                error: io::Error::other(format!("the driver gave {} buffers", req.count)),
            });
        }
        let mut maps = Vec::with_capacity(req.count as usize);
        for index in 0..req.count {
            let mut buf: Buffer = zeroed();
            buf.index = index;
            buf.type_ = BUF_TYPE_VIDEO_CAPTURE;
            buf.memory = MEMORY_MMAP;
            dev.ioctl(VIDIOC_QUERYBUF, "VIDIOC_QUERYBUF", &mut buf)?;
            let len = buf.length as usize;
            // SAFETY: reading the union member the MMAP memory type sets.
            let offset = unsafe { buf.m.offset };
            // SAFETY: maps the driver's buffer `index` at the offset and
            // length it gave; the result is checked before use.
            let ptr = unsafe {
                libc::mmap(
                    std::ptr::null_mut(),
                    len,
                    libc::PROT_READ | libc::PROT_WRITE,
                    libc::MAP_SHARED,
                    dev.fd.as_raw_fd(),
                    offset as libc::off_t,
                )
            };
            if ptr == libc::MAP_FAILED {
                return Err(V4l2Error::Ioctl {
                    path: dev.path.clone(),
                    what: format!("mapping buffer {index}"),
                    error: io::Error::last_os_error(),
                });
            }
            maps.push(Mapping { ptr, len });
            dev.ioctl(VIDIOC_QBUF, "VIDIOC_QBUF", &mut buf)?;
        }
        let mut kind = BUF_TYPE_VIDEO_CAPTURE as libc::c_int;
        dev.ioctl(VIDIOC_STREAMON, "VIDIOC_STREAMON", &mut kind)?;
        Ok(maps)
    }

    /// The device node.
    pub fn path(&self) -> &Path {
        &self.dev.path
    }

    /// The format and size in use.
    pub fn format(&self) -> FormatChoice {
        self.choice
    }

    /// The frame period the driver reports, in seconds.
    pub fn frame_period_s(&self) -> f64 {
        self.frame_period_s
    }

    /// Exposure time now set, in seconds.
    pub fn exposure_s(&self) -> f64 {
        f64::from(self.exposure_units) * 1e-4
    }

    /// The settings level messages name.
    pub fn settings(&self) -> Settings {
        Settings {
            exposure_s: self.exposure_s(),
            gain: self.gain.map(i64::from),
        }
    }

    /// Sets the exposure time (seconds, rounded to the camera's 100 µs).
    pub fn set_exposure(&mut self, exposure_s: f64) -> Result<(), V4l2Error> {
        let units = exposure_units(exposure_s);
        if units != i64::from(self.exposure_units) {
            self.exposure_units =
                self.dev
                    .set_ranged(CID_EXPOSURE_ABSOLUTE, "exposure (100 µs units)", units, "")?;
        }
        Ok(())
    }

    /// Sets the gain control.
    pub fn set_gain(&mut self, gain: i32) -> Result<(), V4l2Error> {
        self.gain = Some(self.dev.set_ranged(CID_GAIN, "gain", i64::from(gain), "")?);
        Ok(())
    }

    /// Waits for the next filled buffer, copies its bytes out and gives it
    /// back to the driver; `None` for a frame the driver marked corrupt.
    fn dequeue(&mut self, deadline_s: f64) -> Result<Option<Dequeued>, V4l2Error> {
        loop {
            let left_ms = ((deadline_s - monotonic_now_s()) * 1e3).ceil();
            if left_ms <= 0.0 {
                return Err(self.timeout(0));
            }
            let mut pfd = libc::pollfd {
                fd: self.dev.fd.as_raw_fd(),
                events: libc::POLLIN,
                revents: 0,
            };
            // SAFETY: one valid pollfd for the duration of the call.
            let r = unsafe { libc::poll(&mut pfd, 1, left_ms.min(1e6) as libc::c_int) };
            if r < 0 {
                let e = io::Error::last_os_error();
                if e.kind() == io::ErrorKind::Interrupted {
                    continue;
                }
                return Err(V4l2Error::Ioctl {
                    path: self.dev.path.clone(),
                    what: "waiting for a frame".into(),
                    error: e,
                });
            }
            if r == 0 {
                continue;
            }
            let mut buf: Buffer = zeroed();
            buf.type_ = BUF_TYPE_VIDEO_CAPTURE;
            buf.memory = MEMORY_MMAP;
            match xioctl(&self.dev.fd, VIDIOC_DQBUF, &mut buf) {
                Ok(()) => {}
                Err(e) if e.raw_os_error() == Some(libc::EAGAIN) => continue,
                Err(source) => {
                    return Err(V4l2Error::Ioctl {
                        path: self.dev.path.clone(),
                        what: "VIDIOC_DQBUF (was the camera unplugged?)".into(),
                        error: source,
                    });
                }
            }
            let map = self.buffers.get(buf.index as usize);
            let bytes = map.map(|m| {
                let used = (buf.bytesused as usize).min(m.len);
                // SAFETY: the driver has handed buffer `index` back (DQBUF)
                // and does not write it until it is queued again below;
                // `used` is within the mapping.
                unsafe { std::slice::from_raw_parts(m.ptr as *const u8, used) }.to_vec()
            });
            self.dev.ioctl(VIDIOC_QBUF, "VIDIOC_QBUF", &mut buf)?;
            let Some(bytes) = bytes else {
                continue;
            };
            if buf.flags & BUF_FLAG_ERROR != 0 || bytes.is_empty() {
                return Ok(None);
            }
            let t = buf.timestamp.tv_sec as f64 + buf.timestamp.tv_usec as f64 * 1e-6;
            return Ok(Some(Dequeued {
                bytes,
                timestamp_s: t,
                flags: buf.flags,
                sequence: buf.sequence,
            }));
        }
    }

    fn timeout(&self, errors: u32) -> V4l2Error {
        V4l2Error::Timeout {
            path: self.dev.path.clone(),
            seconds: self.config.timeout_s,
            errors,
            exposure_ms: self.exposure_s() * 1e3,
        }
    }

    /// The next frame whose exposure began after this call (after any
    /// change of exposure or of the projector's image before it) plus
    /// [`V4l2Config::settle_s`], with its timestamp; not checked for
    /// saturation.
    ///
    /// With monotonic timestamps a frame stamped at the end of its readout
    /// counts when `timestamp - exposure - frame period` is after the call
    /// (the readout takes at most a frame period); without them the
    /// frames that were already queued are dropped.
    pub fn capture_timed(&mut self) -> Result<TimedFrame, V4l2Error> {
        let called = monotonic_now_s() + self.config.settle_s.max(0.0);
        let deadline = called + self.config.timeout_s.max(0.1);
        let exposure_s = self.exposure_s();
        // Without usable timestamps: every queued buffer may hold a frame
        // begun before the call, and one more may be in the making.
        let mut stale = self.buffers.len() + 1;
        let mut errors = 0;
        loop {
            if monotonic_now_s() > deadline {
                return Err(self.timeout(errors));
            }
            let Some(Dequeued {
                bytes,
                timestamp_s: t,
                flags,
                sequence,
            }) = self.dequeue(deadline)?
            else {
                errors += 1;
                continue;
            };
            let start_of_exposure = flags & BUF_FLAG_TSTAMP_SRC_MASK == BUF_FLAG_TSTAMP_SRC_SOE;
            let fresh = if flags & BUF_FLAG_TIMESTAMP_MASK == BUF_FLAG_TIMESTAMP_MONOTONIC {
                let began = if start_of_exposure {
                    t
                } else {
                    t - exposure_s - self.frame_period_s
                };
                began >= called
            } else {
                stale = stale.saturating_sub(1);
                stale == 0
            };
            if !fresh {
                continue;
            }
            let frame =
                decode::decode(&self.layout, &bytes).map_err(|source| V4l2Error::Decode {
                    path: self.dev.path.clone(),
                    error: source,
                })?;
            return Ok(TimedFrame {
                frame,
                timestamp_s: t,
                start_of_exposure,
                sequence,
                exposure_s,
            });
        }
    }
}

impl Drop for V4l2Camera {
    fn drop(&mut self) {
        let mut kind = BUF_TYPE_VIDEO_CAPTURE as libc::c_int;
        let _ = xioctl(&self.dev.fd, VIDIOC_STREAMOFF, &mut kind);
        // The mappings unmap themselves, then the descriptor closes.
        self.buffers.clear();
    }
}

impl CameraDevice for V4l2Camera {
    type Error = V4l2Error;

    fn device(&self) -> &PinholeDevice {
        &self.device
    }

    fn response(&self) -> &CameraResponse {
        &self.response
    }

    /// A frame exposed for `exposure_s` that began after this call
    /// ([`V4l2Camera::capture_timed`]). A free-running camera cannot start
    /// at `start_s` (the sim's clock): the frame's own timestamp says when
    /// it was taken. Stops on a saturated frame.
    fn capture(&mut self, _start_s: f64, exposure_s: f64) -> Result<CameraFrame, V4l2Error> {
        self.set_exposure(exposure_s)?;
        let timed = self.capture_timed()?;
        if let Some(limits) = &self.config.limits {
            check_saturation(&timed.frame, limits, self.settings()).map_err(|source| {
                V4l2Error::Levels {
                    path: self.dev.path.clone(),
                    error: source,
                }
            })?;
        }
        Ok(timed.frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The numbers `videodev2.h` gives on 64-bit Linux: a wrong layout
    /// changes the size encoded in them.
    #[test]
    #[cfg(target_pointer_width = "64")]
    fn ioctl_numbers_match_the_kernel() {
        assert_eq!(VIDIOC_QUERYCAP, 0x8068_5600);
        assert_eq!(VIDIOC_ENUM_FMT, 0xc040_5602);
        assert_eq!(VIDIOC_S_FMT, 0xc0d0_5605);
        assert_eq!(VIDIOC_REQBUFS, 0xc014_5608);
        assert_eq!(VIDIOC_QUERYBUF, 0xc058_5609);
        assert_eq!(VIDIOC_QBUF, 0xc058_560f);
        assert_eq!(VIDIOC_DQBUF, 0xc058_5611);
        assert_eq!(VIDIOC_STREAMON, 0x4004_5612);
        assert_eq!(VIDIOC_STREAMOFF, 0x4004_5613);
        assert_eq!(VIDIOC_G_PARM, 0xc0cc_5615);
        assert_eq!(VIDIOC_S_PARM, 0xc0cc_5616);
        assert_eq!(VIDIOC_G_CTRL, 0xc008_561b);
        assert_eq!(VIDIOC_S_CTRL, 0xc008_561c);
        assert_eq!(VIDIOC_QUERYCTRL, 0xc044_5624);
        assert_eq!(VIDIOC_ENUM_FRAMESIZES, 0xc02c_564a);
        assert_eq!(std::mem::offset_of!(Buffer, timestamp), 24);
        assert_eq!(std::mem::offset_of!(Buffer, m), 64);
        assert_eq!(std::mem::offset_of!(Format, fmt), 8);
    }

    #[test]
    fn exposure_is_in_100_microsecond_units() {
        assert_eq!(exposure_units(0.02), 200);
        assert_eq!(exposure_units(1.0 / 30.0), 333);
        assert_eq!(exposure_units(0.00004), 0);
        assert_eq!(exposure_units(f64::NAN), -1);
    }

    #[test]
    fn a_missing_device_says_what_to_check() {
        let e = list("/dev/showcase-no-such-camera").unwrap_err();
        let text = e.to_string();
        assert!(text.contains("cannot open the camera"), "{text}");
        assert!(text.contains("ls /dev/video*"), "{text}");
        // /dev/null opens but is no camera.
        let e = list("/dev/null").unwrap_err();
        assert!(
            e.to_string()
                .contains("('not a V4L2 device') is not a streaming video capture"),
            "{e}"
        );
    }
}
