//! Fuzz the frame decoder: any bytes must give `Err`, "need more", or a
//! message that validates and round-trips. Run with
//! `cargo +nightly fuzz run decode` from the repository root.
#![no_main]

use libfuzzer_sys::fuzz_target;
use showcase_proto::codec::{FrameDecoder, MAX_FRAME_LEN, decode_frame, encode_frame};
use showcase_proto::Validate;

fuzz_target!(|data: &[u8]| {
    if let Ok(Some((msg, used))) = decode_frame(data, MAX_FRAME_LEN) {
        assert!(used <= data.len());
        assert!(msg.validate().is_ok());
        let again = encode_frame(&msg, MAX_FRAME_LEN).expect("a decoded message re-encodes");
        let (back, _) = decode_frame(&again, MAX_FRAME_LEN).unwrap().unwrap();
        assert_eq!(back, msg);
    }
    // The streaming decoder must agree when fed byte by byte.
    let mut dec = FrameDecoder::new(MAX_FRAME_LEN);
    for b in data.iter().take(4096) {
        dec.push(std::slice::from_ref(b));
        if dec.next_message().is_err() {
            break;
        }
    }
});
