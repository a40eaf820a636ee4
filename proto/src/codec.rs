//! Framing and encoding: each message is a 4-byte little-endian length
//! followed by its bincode 2 (serde) payload. Decoding checks the length
//! against a limit before reading, bounds bincode's allocations by the same
//! limit, rejects trailing bytes, and validates the message.

use crate::message::Message;
use crate::validate::{Validate, ValidationError};

/// Largest frame accepted or produced, in bytes (payload, without prefix).
pub const MAX_FRAME_LEN: usize = 64 << 20;

/// Bytes of the length prefix.
pub const PREFIX_LEN: usize = 4;

const CONFIG: bincode::config::Configuration<
    bincode::config::LittleEndian,
    bincode::config::Varint,
    bincode::config::Limit<MAX_FRAME_LEN>,
> = bincode::config::standard().with_limit::<MAX_FRAME_LEN>();

/// Why a frame could not be encoded or decoded.
#[derive(Debug, thiserror::Error)]
pub enum CodecError {
    /// The length prefix (or an encoded message) exceeds the limit.
    #[error("frame of {len} bytes exceeds the limit of {limit} bytes")]
    TooLarge {
        /// Claimed or actual payload length.
        len: usize,
        /// The limit in force.
        limit: usize,
    },
    /// The payload is not a well-formed message.
    #[error("malformed message: {0}")]
    Malformed(String),
    /// The payload decoded but bytes were left over.
    #[error("{extra} trailing bytes after a {kind} message")]
    Trailing {
        /// The message kind that decoded.
        kind: &'static str,
        /// Bytes left over.
        extra: usize,
    },
    /// The message decoded but broke an invariant.
    #[error("invalid message: {0}")]
    Invalid(#[from] ValidationError),
    /// The message could not be encoded.
    #[error("cannot encode message: {0}")]
    Encode(String),
}

/// Encode a message as one length-prefixed frame, refusing frames over `limit`.
pub fn encode_frame(msg: &Message, limit: usize) -> Result<Vec<u8>, CodecError> {
    let limit = limit.min(MAX_FRAME_LEN);
    let mut out = vec![0u8; PREFIX_LEN];
    bincode::serde::encode_into_std_write(msg, &mut out, CONFIG)
        .map_err(|e| CodecError::Encode(e.to_string()))?;
    let len = out.len() - PREFIX_LEN;
    if len > limit {
        return Err(CodecError::TooLarge { len, limit });
    }
    out[..PREFIX_LEN].copy_from_slice(&(len as u32).to_le_bytes());
    Ok(out)
}

/// Decode and validate one payload (without its length prefix).
pub fn decode_payload(payload: &[u8]) -> Result<Message, CodecError> {
    if payload.len() > MAX_FRAME_LEN {
        return Err(CodecError::TooLarge {
            len: payload.len(),
            limit: MAX_FRAME_LEN,
        });
    }
    let (msg, used): (Message, usize) = bincode::serde::decode_from_slice(payload, CONFIG)
        .map_err(|e| CodecError::Malformed(e.to_string()))?;
    if used != payload.len() {
        return Err(CodecError::Trailing {
            kind: msg.kind(),
            extra: payload.len() - used,
        });
    }
    msg.validate()?;
    Ok(msg)
}

/// Decode the first frame of `buf`. `Ok(None)` means the frame is not
/// complete yet (read more); `Ok(Some((msg, n)))` consumed `n` bytes.
pub fn decode_frame(buf: &[u8], limit: usize) -> Result<Option<(Message, usize)>, CodecError> {
    let limit = limit.min(MAX_FRAME_LEN);
    let Some(prefix) = buf.get(..PREFIX_LEN) else {
        return Ok(None);
    };
    let len = u32::from_le_bytes(prefix.try_into().expect("prefix is 4 bytes")) as usize;
    if len > limit {
        return Err(CodecError::TooLarge { len, limit });
    }
    let Some(payload) = buf.get(PREFIX_LEN..PREFIX_LEN + len) else {
        return Ok(None);
    };
    Ok(Some((decode_payload(payload)?, PREFIX_LEN + len)))
}

/// Incremental decoder over a byte stream: push what arrives, pop messages.
#[derive(Debug)]
pub struct FrameDecoder {
    buf: Vec<u8>,
    limit: usize,
}

impl FrameDecoder {
    /// A decoder that refuses frames over `limit` bytes.
    pub fn new(limit: usize) -> Self {
        Self {
            buf: Vec::new(),
            limit: limit.min(MAX_FRAME_LEN),
        }
    }

    /// Append received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// The next complete message, `Ok(None)` if more bytes are needed. After
    /// an error the stream is unusable: the peer must be closed.
    pub fn next_message(&mut self) -> Result<Option<Message>, CodecError> {
        match decode_frame(&self.buf, self.limit)? {
            Some((msg, used)) => {
                self.buf.drain(..used);
                Ok(Some(msg))
            }
            None => Ok(None),
        }
    }

    /// Bytes buffered but not yet decoded.
    pub fn buffered(&self) -> usize {
        self.buf.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Every valid message survives encode -> decode unchanged.
        #[test]
        fn every_message_round_trips(msg in testing::message()) {
            prop_assert_eq!(msg.validate(), Ok(()));
            let frame = encode_frame(&msg, MAX_FRAME_LEN).unwrap();
            let (back, used) = decode_frame(&frame, MAX_FRAME_LEN).unwrap().unwrap();
            prop_assert_eq!(used, frame.len());
            prop_assert_eq!(back, msg);
        }

        /// A stream split at arbitrary points yields the same messages.
        #[test]
        fn stream_reassembles_across_splits(
            msgs in proptest::collection::vec(testing::message(), 1..6),
            chunk in 1usize..97,
        ) {
            let bytes: Vec<u8> = msgs
                .iter()
                .flat_map(|m| encode_frame(m, MAX_FRAME_LEN).unwrap())
                .collect();
            let mut dec = FrameDecoder::new(MAX_FRAME_LEN);
            let mut out = Vec::new();
            for part in bytes.chunks(chunk) {
                dec.push(part);
                while let Some(m) = dec.next_message().unwrap() {
                    out.push(m);
                }
            }
            prop_assert_eq!(dec.buffered(), 0);
            prop_assert_eq!(out, msgs);
        }
    }

    #[test]
    fn oversized_prefix_is_refused_before_reading() {
        let mut buf = ((MAX_FRAME_LEN + 1) as u32).to_le_bytes().to_vec();
        buf.extend_from_slice(&[0; 8]);
        let err = decode_frame(&buf, MAX_FRAME_LEN).unwrap_err();
        assert!(matches!(err, CodecError::TooLarge { .. }), "{err}");
        let err = decode_frame(&1000u32.to_le_bytes(), 999).unwrap_err();
        assert!(
            err.to_string()
                .contains("1000 bytes exceeds the limit of 999"),
            "{err}"
        );
    }

    #[test]
    fn trailing_bytes_and_invalid_values_are_errors() {
        let msg = Message::Swap(crate::Swap { frame: 7 });
        let mut frame = encode_frame(&msg, MAX_FRAME_LEN).unwrap();
        frame.push(0);
        let len = (frame.len() - PREFIX_LEN) as u32;
        frame[..4].copy_from_slice(&len.to_le_bytes());
        let err = decode_frame(&frame, MAX_FRAME_LEN).unwrap_err();
        assert!(
            err.to_string().contains("1 trailing bytes after a Swap"),
            "{err}"
        );

        let bad = Message::NodeStats(crate::NodeStats {
            frame: 1,
            render_ms: f32::NAN,
            barrier_wait_ms: 0.0,
            present_time_ns: 0,
        });
        let frame = encode_frame(&bad, MAX_FRAME_LEN).unwrap();
        let err = decode_frame(&frame, MAX_FRAME_LEN).unwrap_err();
        assert!(err.to_string().contains("NodeStats.render_ms"), "{err}");
    }

    #[test]
    fn incomplete_frames_ask_for_more() {
        let frame = encode_frame(&Message::Swap(crate::Swap { frame: 3 }), MAX_FRAME_LEN).unwrap();
        for cut in 0..frame.len() {
            assert!(
                decode_frame(&frame[..cut], MAX_FRAME_LEN)
                    .unwrap()
                    .is_none()
            );
        }
    }
}
