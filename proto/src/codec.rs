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
