//! Messages over one QUIC bidirectional stream, framed by proto's codec.

use showcase_proto::Message;
use showcase_proto::codec::{CodecError, FrameDecoder, MAX_FRAME_LEN, encode_frame};

/// Why a stream failed.
#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    /// The peer sent bytes that are not a valid message.
    #[error("bad message from peer: {0}")]
    Codec(#[from] CodecError),
    /// Reading failed.
    #[error("read: {0}")]
    Read(#[from] quinn::ReadError),
    /// Writing failed.
    #[error("write: {0}")]
    Write(#[from] quinn::WriteError),
    /// The peer finished its stream.
    #[error("peer closed the stream")]
    Closed,
}

/// A framed message stream over a QUIC bidirectional stream.
#[derive(Debug)]
pub struct MessageStream {
    send: quinn::SendStream,
    recv: quinn::RecvStream,
    decoder: FrameDecoder,
    buf: Vec<u8>,
}

impl MessageStream {
    /// Wrap an opened or accepted bidirectional stream.
    pub fn new(send: quinn::SendStream, recv: quinn::RecvStream) -> Self {
        Self {
            send,
            recv,
            decoder: FrameDecoder::new(MAX_FRAME_LEN),
            buf: vec![0; 64 * 1024],
        }
    }

    /// Send one message.
    pub async fn send(&mut self, msg: &Message) -> Result<(), StreamError> {
        let frame = encode_frame(msg, MAX_FRAME_LEN)?;
        self.send.write_all(&frame).await?;
        Ok(())
    }

    /// Receive the next message. Cancel-safe: bytes already read stay
    /// buffered in the decoder.
    pub async fn recv(&mut self) -> Result<Message, StreamError> {
        loop {
            if let Some(msg) = self.decoder.next_message()? {
                return Ok(msg);
            }
            match self.recv.read(&mut self.buf).await? {
                Some(n) => self.decoder.push(&self.buf[..n]),
                None => return Err(StreamError::Closed),
            }
        }
    }

    /// Split into the raw halves (for drivers that read and write from
    /// different tasks).
    pub fn into_inner(self) -> (quinn::SendStream, quinn::RecvStream) {
        (self.send, self.recv)
    }
}
