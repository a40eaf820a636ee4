//! Real cameras without a camera: decoding of frames that real encoders
//! made (ffmpeg; `tests/fixtures/camera/make.sh`), the missing-Huffman-table
//! MJPEG of UVC cameras, and the recorded camera's replay and errors.

use showcase_light::Image;
use showcase_light::hardware::{CameraDevice, CameraFrame};
use showcase_proto::{CameraResponse, PinholeDevice};
use showcase_render::camera::decode::{self, FrameLayout, PixelFormat};
use showcase_render::camera::recorded::{INDEX, RecordedCamera, RecordedError, Recorder};
use showcase_render::camera::{LevelError, LevelLimits, Settings, TimedFrame, check_levels};
use std::path::{Path, PathBuf};

const W: u32 = 160;
const H: u32 = 120;

fn fixture(name: &str) -> Vec<u8> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/camera")
        .join(name);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The source pattern (binary PPM, maxval 255).
fn pattern() -> Image<[u16; 3]> {
    let data = fixture("pattern.ppm");
    let header = b"P6\n160 120\n255\n";
    assert_eq!(&data[..header.len()], header);
    let px = &data[header.len()..];
    assert_eq!(px.len(), (W * H * 3) as usize);
    Image::from_fn(W, H, |x, y| {
        let i = ((y * W + x) * 3) as usize;
        [px[i], px[i + 1], px[i + 2]].map(u16::from)
    })
}

/// Mean and largest absolute difference over every channel, and PSNR (dB).
fn compare(
    a: &Image<[u16; 3]>,
    b: &Image<[u16; 3]>,
    only: impl Fn(u32, u32) -> bool,
) -> (f64, u16, f64) {
    assert!(a.same_size(b));
    let (mut sum, mut sq, mut max, mut n) = (0.0, 0.0, 0u16, 0usize);
    for y in 0..a.height {
        for x in 0..a.width {
            if !only(x, y) {
                continue;
            }
            let (p, q) = (a.get(x, y).unwrap(), b.get(x, y).unwrap());
            for c in 0..3 {
                let d = p[c].abs_diff(q[c]);
                sum += f64::from(d);
                sq += f64::from(d) * f64::from(d);
                max = max.max(d);
                n += 1;
            }
        }
    }
    let mse = sq / n as f64;
    (
        sum / n as f64,
        max,
        10.0 * (255.0f64 * 255.0 / mse.max(1e-12)).log10(),
    )
}

/// Inside the pattern's flat patches, away from their edges (where the
/// encoder's chroma filter blends neighbours).
fn in_patch(x: u32, y: u32) -> bool {
    let patches = [(8, 8), (40, 8), (72, 8), (104, 8), (8, 88), (40, 88)];
    patches
        .iter()
        .any(|&(px, py)| (px + 4..px + 20).contains(&x) && (py + 4..py + 20).contains(&y))
}

#[test]
fn yuyv_from_ffmpeg_decodes_to_the_pattern() {
    let layout = FrameLayout::packed(PixelFormat::Yuyv, W, H);
    let frame = decode::decode(&layout, &fixture("pattern.yuyv")).unwrap();
    assert_eq!(frame.bits, 8);
    let truth = pattern();
    // Flat colours survive 4:2:2 and BT.601 limited range to a code
    // (measured: mean 0.93, PSNR 45.9 dB).
    let (_, max, _) = compare(&frame.codes, &truth, in_patch);
    assert!(max <= 1, "flat patches off by {max}");
    let (mean, _, psnr) = compare(&frame.codes, &truth, |_, _| true);
    assert!(mean < 1.2 && psnr > 43.0, "mean {mean}, PSNR {psnr} dB");
    // A stride with padding reads the same pixels.
    let mut padded = Vec::new();
    for row in fixture("pattern.yuyv").chunks(W as usize * 2) {
        padded.extend_from_slice(row);
        padded.extend_from_slice(&[0xAB; 64]);
    }
    let mut layout = layout;
    layout.bytes_per_line = W * 2 + 64;
    assert_eq!(decode::decode(&layout, &padded).unwrap(), frame);
}

#[test]
fn nv12_from_ffmpeg_decodes_to_the_pattern() {
    let layout = FrameLayout::packed(PixelFormat::Nv12, W, H);
    let frame = decode::decode(&layout, &fixture("pattern.nv12")).unwrap();
    let truth = pattern();
    let (_, max, _) = compare(&frame.codes, &truth, in_patch);
    assert!(max <= 1, "flat patches off by {max}");
    let (mean, _, psnr) = compare(&frame.codes, &truth, |_, _| true);
    assert!(mean < 1.2 && psnr > 40.0, "mean {mean}, PSNR {psnr} dB");
}

#[test]
fn mjpeg_from_ffmpeg_decodes_to_the_pattern() {
    let layout = FrameLayout::packed(PixelFormat::Mjpeg, W, H);
    let frame = decode::decode(&layout, &fixture("pattern.jpg")).unwrap();
    assert_eq!(frame.bits, 8);
    // ffmpeg -q:v 3, 4:2:2 (measured: mean 1.32, PSNR 34.0 dB, flat
    // patches within 3 codes).
    let (mean, _, psnr) = compare(&frame.codes, &pattern(), |_, _| true);
    assert!(psnr > 32.0 && mean < 2.0, "mean {mean}, PSNR {psnr} dB");
    let (_, max, _) = compare(&frame.codes, &pattern(), in_patch);
    assert!(max <= 5, "flat patches off by {max}");
    // A camera set to another size than the JPEG's is an error.
    let wrong = FrameLayout::packed(PixelFormat::Mjpeg, 320, 240);
    let e = decode::decode(&wrong, &fixture("pattern.jpg")).unwrap_err();
    assert!(
        e.to_string()
            .contains("is 160x120, the camera was set to 320x240"),
        "{e}"
    );
}

#[test]
fn mjpeg_without_huffman_tables_decodes_like_the_full_jpeg() {
    let full = fixture("pattern.jpg");
    let bare = fixture("pattern-no-dht.jpg");
    assert!(
        !bare.windows(2).any(|w| w == [0xFF, 0xC4]),
        "the fixture still has a DHT"
    );
    // The standard tables go where ffmpeg put its own: the same file.
    assert_eq!(&*decode::with_huffman_tables(&bare), &full[..]);
    assert_eq!(&*decode::with_huffman_tables(&full), &full[..]);
    let layout = FrameLayout::packed(PixelFormat::Mjpeg, W, H);
    assert_eq!(
        decode::decode(&layout, &bare).unwrap(),
        decode::decode(&layout, &full).unwrap()
    );
}

#[test]
fn damaged_mjpeg_frames_do_not_panic() {
    let full = fixture("pattern-no-dht.jpg");
    let layout = FrameLayout::packed(PixelFormat::Mjpeg, W, H);
    for cut in [0, 2, 10, 100, full.len() / 2, full.len() - 2] {
        let _ = decode::decode(&layout, &full[..cut]);
    }
    let mut flipped = full.clone();
    for i in (20..flipped.len()).step_by(37) {
        flipped[i] ^= 0x5A;
        let _ = decode::decode(&layout, &flipped);
    }
    assert!(decode::decode(&layout, &full[..100]).is_err());
}

#[test]
fn the_white_patch_saturates_the_level_check() {
    let layout = FrameLayout::packed(PixelFormat::Yuyv, W, H);
    let frame = decode::decode(&layout, &fixture("pattern.yuyv")).unwrap();
    let settings = Settings {
        exposure_s: 0.01,
        gain: Some(32),
    };
    match check_levels(&frame, &LevelLimits::default(), settings) {
        Err(e @ LevelError::Saturated { .. }) => {
            assert!(
                e.to_string().contains("lower the exposure or the gain"),
                "{e}"
            );
        }
        other => panic!("{other:?}"),
    }
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("showcase-camera-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn device() -> PinholeDevice {
    PinholeDevice::look_at(
        glam::DVec3::new(0.0, 0.0, -2.0),
        glam::DVec3::ZERO,
        glam::DVec3::Y,
        50.0,
        W,
        H,
    )
}

fn timed(frame: CameraFrame, k: u32, exposure_s: f64) -> TimedFrame {
    TimedFrame {
        frame,
        timestamp_s: 100.0 + f64::from(k) / 30.0,
        start_of_exposure: false,
        sequence: k,
        exposure_s,
    }
}

/// A recording of the YUYV and MJPEG fixture frames at 10 ms.
fn record(dir: &Path) -> Vec<CameraFrame> {
    let frames: Vec<CameraFrame> = [
        ("pattern.yuyv", PixelFormat::Yuyv),
        ("pattern.jpg", PixelFormat::Mjpeg),
    ]
    .into_iter()
    .map(|(name, format)| {
        decode::decode(&FrameLayout::packed(format, W, H), &fixture(name)).unwrap()
    })
    .collect();
    let response = CameraResponse {
        exposure_s: 0.01,
        ..CameraResponse::default()
    };
    let mut rec = Recorder::create(dir, device(), response).unwrap();
    for (k, f) in frames.iter().enumerate() {
        rec.push(&timed(f.clone(), k as u32, 0.01)).unwrap();
    }
    rec.finish().unwrap();
    frames
}

#[test]
fn a_recorded_camera_replays_its_frames() {
    let dir = scratch("replay");
    let frames = record(&dir);
    let mut cam = RecordedCamera::open(&dir).unwrap();
    assert_eq!(cam.device(), &device());
    assert_eq!(cam.response().exposure_s, 0.01);
    assert_eq!(cam.capture(0.0, 0.01).unwrap(), frames[0]);
    // A capture asking another exposure than was recorded is refused.
    let e = cam.capture(0.0, 0.02).unwrap_err();
    assert!(
        e.to_string()
            .contains("recorded with a 10.000 ms exposure, the capture asks 20.000 ms"),
        "{e}"
    );
    let t = cam.next_frame().unwrap();
    assert_eq!(t.frame, frames[1]);
    assert_eq!((t.sequence, t.timestamp_s), (1, 100.0 + 1.0 / 30.0));
    let e = cam.capture(0.0, 0.01).unwrap_err();
    assert!(
        matches!(e, RecordedError::Exhausted { frames: 2, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("holds 2 frames"), "{e}");
    cam.rewind();
    assert_eq!(cam.remaining(), 2);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_recording_with_more_than_8_bits_round_trips() {
    let dir = scratch("wide");
    let response = CameraResponse {
        bits: 12,
        ..CameraResponse::default()
    };
    let frame = CameraFrame {
        codes: Image::from_fn(W, H, |x, y| [(x * 25) as u16, (y * 34) as u16, 4095]),
        bits: 12,
    };
    let mut rec = Recorder::create(&dir, device(), response).unwrap();
    rec.push(&timed(frame.clone(), 0, 1.0 / 30.0)).unwrap();
    // A frame of another depth does not join the recording.
    let eight = CameraFrame {
        bits: 8,
        ..frame.clone()
    };
    assert!(rec.push(&timed(eight, 1, 1.0 / 30.0)).is_err());
    rec.finish().unwrap();
    let mut cam = RecordedCamera::open(&dir).unwrap();
    assert_eq!(cam.capture(0.0, 1.0 / 30.0).unwrap(), frame);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Opening `dir` fails with a message containing `needle`.
fn open_fails(dir: &Path, needle: &str) {
    match RecordedCamera::open(dir) {
        Ok(_) => panic!("{} opened", dir.display()),
        Err(e) => assert!(e.to_string().contains(needle), "{e}"),
    }
}

fn edit_index(dir: &Path, edit: impl FnOnce(&mut serde_json::Value)) {
    let path = dir.join(INDEX);
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    edit(&mut v);
    std::fs::write(&path, v.to_string()).unwrap();
}

#[test]
fn broken_recordings_are_clear_errors() {
    let dir = scratch("broken");
    open_fails(&dir, "No such file");
    std::fs::create_dir_all(&dir).unwrap();
    open_fails(&dir, "this folder is no recording");
    record(&dir);
    let good = std::fs::read_to_string(dir.join(INDEX)).unwrap();
    let reset = || std::fs::write(dir.join(INDEX), &good).unwrap();

    std::fs::write(dir.join(INDEX), "{ not json").unwrap();
    open_fails(&dir, "not a recorded camera's index");
    reset();
    edit_index(&dir, |v| v["format"] = "something-else/2".into());
    open_fails(&dir, "this build reads");
    reset();
    edit_index(&dir, |v| v["frames"] = serde_json::json!([]));
    open_fails(&dir, "no frames");
    reset();
    edit_index(&dir, |v| v["bits"] = 10.into());
    open_fails(&dir, "the frames have 10 bits, the response 8 bits");
    reset();
    edit_index(&dir, |v| v["frames"][1]["file"] = "../../etc/passwd".into());
    open_fails(&dir, "must be a plain file name inside the folder");
    reset();
    edit_index(&dir, |v| v["frames"][0]["exposure_s"] = (-1.0).into());
    open_fails(&dir, "the exposure not negative");
    reset();

    // A missing frame file is found at open.
    std::fs::rename(dir.join("frame-00001.png"), dir.join("moved.png")).unwrap();
    open_fails(&dir, "frame 1 of camera.json is missing");
    // A short recording: frame 1 replaced by a frame of another size, and
    // then by a file that is no PNG; both fail at replay, not at open.
    let small = CameraFrame {
        codes: Image::new(8, 8, [1, 2, 3]),
        bits: 8,
    };
    let other = scratch("broken-small");
    let mut rec = Recorder::create(
        &other,
        PinholeDevice {
            width: 8,
            height: 8,
            ..device()
        },
        CameraResponse::default(),
    )
    .unwrap();
    rec.push(&timed(small, 0, 0.01)).unwrap();
    rec.finish().unwrap();
    std::fs::copy(other.join("frame-00000.png"), dir.join("frame-00001.png")).unwrap();
    let mut cam = RecordedCamera::open(&dir).unwrap();
    cam.next_frame().unwrap();
    let e = cam.next_frame().unwrap_err();
    assert!(
        e.to_string()
            .contains("8x8 pixels, the recorded camera is 160x120"),
        "{e}"
    );
    std::fs::write(dir.join("frame-00001.png"), b"\x89PNG\r\n\x1a\n truncated").unwrap();
    let mut cam = RecordedCamera::open(&dir).unwrap();
    cam.next_frame().unwrap();
    let e = cam.next_frame().unwrap_err();
    assert!(e.to_string().contains("not a readable PNG"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
    std::fs::remove_dir_all(&other).unwrap();
}
