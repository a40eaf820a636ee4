//! Capture messages: frames split into chunks and put back together
//! exactly; chunks out of order, oversized or mismatched are refused with
//! an error that says which; every capture message survives the codec.

use proptest::prelude::*;
use showcase_proto::capture::{
    ChunkError, FrameAssembler, FrameChunk, FrameCodes, MAX_CHUNK_BYTES, Pattern, split_frame,
};
use showcase_proto::codec::{MAX_FRAME_LEN, decode_frame, encode_frame};
use showcase_proto::{Message, Validate, testing};

fn frame(width: u32, height: u32, seed: u16) -> FrameCodes {
    FrameCodes {
        width,
        height,
        bits: 12,
        codes: (0..width * height)
            .map(|i| {
                let v = (i as u16).wrapping_mul(31).wrapping_add(seed) & 0x0fff;
                [v, v ^ 5, v / 2]
            })
            .collect(),
    }
}

fn chunks_of(frames: &[FrameCodes], id: u64, size: usize) -> Vec<FrameChunk> {
    let n = frames.len() as u32;
    frames
        .iter()
        .enumerate()
        .flat_map(|(i, f)| split_frame(id, i as u32, n, f, size))
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any frames, any chunk size: through the codec and the assembler,
    /// the same codes come out.
    #[test]
    fn chunked_frames_round_trip(
        f in prop::collection::vec(testing::frame_codes(), 1..4),
        size in 1usize..300,
    ) {
        // One capture: every frame the size of the first.
        let frames: Vec<FrameCodes> = f
            .iter()
            .map(|x| FrameCodes { width: f[0].width, height: f[0].height, bits: f[0].bits,
                codes: x.codes.iter().cycle().take(f[0].codes.len()).copied().collect() })
            .collect();
        let mut a = FrameAssembler::new(9, frames.len() as u32, Some((frames[0].width, frames[0].height)));
        for c in chunks_of(&frames, 9, size) {
            let bytes = encode_frame(&Message::FrameChunk(Box::new(c)), MAX_FRAME_LEN).unwrap();
            let (m, _) = decode_frame(&bytes, MAX_FRAME_LEN).unwrap().unwrap();
            let Message::FrameChunk(c) = m else { panic!("not a chunk") };
            a.push(&c).unwrap();
        }
        prop_assert!(a.is_complete());
        prop_assert_eq!(a.take(), frames);
    }

    /// Every capture message validates and survives the codec.
    #[test]
    fn capture_messages_round_trip(m in testing::capture_message()) {
        prop_assert!(m.validate().is_ok(), "{:?}", m.validate());
        let bytes = encode_frame(&m, MAX_FRAME_LEN).unwrap();
        let (back, _) = decode_frame(&bytes, MAX_FRAME_LEN).unwrap().unwrap();
        prop_assert_eq!(back, m);
    }

    /// A mask pattern's pixels are the flags it was made from.
    #[test]
    fn mask_patterns_keep_their_pixels(w in 1u32..20, h in 1u32..20, bits in any::<u64>()) {
        let flags: Vec<bool> = (0..w * h).map(|i| bits.rotate_left(i % 64) & 1 == 1).collect();
        let p = Pattern::mask(w, h, flags.iter().copied(), [0.5, 1.0, 0.25]);
        prop_assert!(p.validate().is_ok());
        let px = p.pixels(w, h);
        for (f, v) in flags.iter().zip(&px) {
            prop_assert_eq!(*v, if *f { [0.5, 1.0, 0.25] } else { [0.0; 3] });
        }
    }
}

/// Out of order, oversized, mismatched, foreign and extra chunks are each
/// refused with their own error.
#[test]
fn bad_chunks_are_refused_with_a_clear_error() {
    let frames = [frame(8, 4, 1), frame(8, 4, 2)];
    let good = chunks_of(&frames, 3, 64); // 192 bytes a frame: 3 chunks each
    assert_eq!(good.len(), 6);
    let fresh = || FrameAssembler::new(3, 2, Some((8, 4)));

    // Out of order: chunk 1 before chunk 0.
    let e = fresh().push(&good[1]).unwrap_err();
    assert!(matches!(e, ChunkError::OutOfOrder { .. }), "{e}");
    assert!(e.to_string().contains("out of order"), "{e}");

    // Oversized: a chunk with more bytes than the frame has left.
    let mut a = fresh();
    let mut big = good[0].clone();
    big.bytes = vec![0; 8 * 4 * 6 + 1];
    let e = a.push(&big).unwrap_err();
    assert!(matches!(e, ChunkError::Oversized { .. }), "{e}");
    assert!(e.to_string().contains("oversized"), "{e}");

    // Over the per-chunk limit: refused by validation (and by the codec).
    let mut huge = good[0].clone();
    huge.width = 1024;
    huge.height = 1024;
    huge.bytes = vec![0; MAX_CHUNK_BYTES + 1];
    assert!(huge.validate().unwrap_err().to_string().contains("at most"));
    let bytes = encode_frame(&Message::FrameChunk(Box::new(huge)), MAX_FRAME_LEN).unwrap();
    assert!(decode_frame(&bytes, MAX_FRAME_LEN).is_err());

    // Mismatched: a frame of another size than the camera's.
    let wrong = chunks_of(&[frame(4, 8, 1)], 3, 64);
    let e = FrameAssembler::new(3, 1, Some((8, 4)))
        .push(&wrong[0])
        .unwrap_err();
    assert!(matches!(e, ChunkError::Mismatch(_)), "{e}");
    assert!(e.to_string().contains("the camera is 8x4"), "{e}");

    // Mismatched within a frame: the second chunk changes the bit depth.
    let mut a = fresh();
    a.push(&good[0]).unwrap();
    let mut odd = good[1].clone();
    odd.bits = 10;
    let e = a.push(&odd).unwrap_err();
    assert!(e.to_string().contains("its first chunk said"), "{e}");

    // Another capture's chunk.
    let e = FrameAssembler::new(4, 2, None).push(&good[0]).unwrap_err();
    assert!(matches!(e, ChunkError::WrongCapture { .. }), "{e}");

    // A frame cut short: its last chunk came with bytes missing.
    let mut a = fresh();
    a.push(&good[0]).unwrap();
    a.push(&good[1]).unwrap();
    let mut short = good[2].clone();
    short.bytes.pop();
    let e = a.push(&short).unwrap_err();
    assert!(matches!(e, ChunkError::Short { .. }), "{e}");

    // All in order: complete; one more is extra.
    let mut a = fresh();
    for c in &good {
        a.push(c).unwrap();
    }
    assert!(a.is_complete());
    let e = a.push(&good[0]).unwrap_err();
    assert!(matches!(e, ChunkError::Extra { .. }), "{e}");
}
