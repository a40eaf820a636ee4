//! Decoder robustness: at least 100,000 random and mutated frames must
//! produce only `Err`, "need more bytes", or messages that validate and
//! round-trip, never a panic, and never an allocation beyond the frame
//! size limit.

use crate::alloc_track::peak_bytes;
use proptest::strategy::{Strategy, ValueTree};
use proptest::test_runner::TestRunner;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use showcase_proto::codec::{MAX_FRAME_LEN, PREFIX_LEN, decode_frame, encode_frame};
use showcase_proto::{Bye, Message, Validate, testing};

/// Valid frames to mutate: a few hundred generated messages of every kind.
fn corpus() -> Vec<Vec<u8>> {
    let mut runner = TestRunner::deterministic();
    let strategy = testing::message();
    (0..300)
        .map(|_| {
            let msg = strategy.new_tree(&mut runner).unwrap().current();
            encode_frame(&msg, MAX_FRAME_LEN).unwrap()
        })
        .collect()
}

fn mutate(rng: &mut ChaCha8Rng, corpus: &[Vec<u8>]) -> Vec<u8> {
    let base = &corpus[rng.random_range(0..corpus.len())];
    let mut f = base.clone();
    match rng.random_range(0..7) {
        // Pure noise, with or without a plausible prefix.
        0 => {
            let n = rng.random_range(0..256);
            f = (0..n).map(|_| rng.random()).collect();
            if rng.random_bool(0.5) && n >= PREFIX_LEN {
                f[..PREFIX_LEN].copy_from_slice(&((n - PREFIX_LEN) as u32).to_le_bytes());
            }
        }
        // Flip a few bits of the payload.
        1 => {
            for _ in 0..rng.random_range(1..6) {
                let i = rng.random_range(PREFIX_LEN.min(f.len() - 1)..f.len());
                f[i] ^= 1 << rng.random_range(0..8);
            }
        }
        // Overwrite bytes with values that are large varint markers.
        2 => {
            for _ in 0..rng.random_range(1..4) {
                let i = rng.random_range(PREFIX_LEN.min(f.len() - 1)..f.len());
                f[i] = [0xfb, 0xfc, 0xfd, 0xfe, 0xff][rng.random_range(0..5)];
            }
        }
        // Truncate (keeping or fixing the prefix).
        3 => {
            f.truncate(rng.random_range(0..f.len()));
            if rng.random_bool(0.5) && f.len() >= PREFIX_LEN {
                let n = (f.len() - PREFIX_LEN) as u32;
                f[..PREFIX_LEN].copy_from_slice(&n.to_le_bytes());
            }
        }
        // Append garbage and fix the prefix: trailing bytes.
        4 => {
            for _ in 0..rng.random_range(1..16) {
                f.push(rng.random());
            }
            let n = (f.len() - PREFIX_LEN) as u32;
            f[..PREFIX_LEN].copy_from_slice(&n.to_le_bytes());
        }
        // A lying length prefix, sometimes over the limit.
        5 => {
            let n: u32 = if rng.random_bool(0.5) {
                rng.random()
            } else {
                rng.random_range(0..f.len() as u32 * 2)
            };
            f[..PREFIX_LEN].copy_from_slice(&n.to_le_bytes());
        }
        // Splice the head of one frame onto the tail of another.
        _ => {
            let other = &corpus[rng.random_range(0..corpus.len())];
            let cut = rng.random_range(PREFIX_LEN..f.len().max(PREFIX_LEN + 1));
            let cut2 = rng.random_range(0..other.len());
            f.truncate(cut);
            f.extend_from_slice(&other[cut2..]);
            let n = (f.len() - PREFIX_LEN) as u32;
            f[..PREFIX_LEN].copy_from_slice(&n.to_le_bytes());
        }
    }
    f
}

#[test]
fn decoder_survives_100k_random_and_mutated_frames() {
    let corpus = corpus();
    let mut rng = ChaCha8Rng::seed_from_u64(0x5c0_ca5e);
    let (mut ok, mut err, mut incomplete, mut max_peak) = (0u32, 0u32, 0u32, 0usize);
    for _ in 0..100_000 {
        let frame = mutate(&mut rng, &corpus);
        let (result, peak) = peak_bytes(|| decode_frame(&frame, MAX_FRAME_LEN));
        max_peak = max_peak.max(peak);
        assert!(
            peak <= MAX_FRAME_LEN,
            "decoding {} bytes allocated {peak} bytes",
            frame.len()
        );
        match result {
            Ok(Some((msg, used))) => {
                ok += 1;
                assert!(used <= frame.len());
                assert_eq!(msg.validate(), Ok(()), "decoder let through {msg:?}");
                let again = encode_frame(&msg, MAX_FRAME_LEN).unwrap();
                let (back, _) = decode_frame(&again, MAX_FRAME_LEN).unwrap().unwrap();
                assert_eq!(back, msg);
            }
            Ok(None) => incomplete += 1,
            Err(e) => {
                err += 1;
                assert!(!e.to_string().is_empty());
            }
        }
    }
    eprintln!("decoded {ok}, rejected {err}, incomplete {incomplete}, peak alloc {max_peak} B");
    // Every outcome must actually occur, or the mutations are not exercising the decoder.
    assert!(
        ok > 1_000 && err > 10_000 && incomplete > 1_000,
        "{ok} {err} {incomplete}"
    );
}

/// A tiny frame that claims a huge string: the claim is checked against the
/// limit before anything is allocated.
#[test]
fn huge_length_claims_do_not_allocate() {
    let frame = encode_frame(
        &Message::Bye(Bye {
            reason: String::new(),
        }),
        MAX_FRAME_LEN,
    )
    .unwrap();
    // Payload: [variant, len]; replace the length by a u64 varint claim.
    for claim in [u64::MAX / 2, (MAX_FRAME_LEN as u64) * 4] {
        let mut f = frame[..PREFIX_LEN + 1].to_vec();
        f.push(0xfd);
        f.extend_from_slice(&claim.to_le_bytes());
        let n = (f.len() - PREFIX_LEN) as u32;
        f[..PREFIX_LEN].copy_from_slice(&n.to_le_bytes());
        let (result, peak) = peak_bytes(|| decode_frame(&f, MAX_FRAME_LEN));
        let e = result.expect_err("a 14-byte frame cannot hold that string");
        assert!(e.to_string().starts_with("malformed message"), "{e}");
        assert!(peak < 4096, "claim {claim} allocated {peak} bytes");
    }
}
