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
    #[error("read: {}{}", .0, why_lost(self))]
    Read(#[from] quinn::ReadError),
    /// Writing failed.
    #[error("write: {}{}", .0, why_lost(self))]
    Write(#[from] quinn::WriteError),
    /// The peer finished its stream.
    #[error("peer closed the stream")]
    Closed,
}

/// QUIC application close code of a master that refuses a node's Hello
/// (name, certificate and roster disagree): retrying cannot help.
pub const REFUSED: u32 = 3;

impl StreamError {
    /// Why the connection was lost, when that is what failed the stream.
    pub fn connection_lost(&self) -> Option<&quinn::ConnectionError> {
        match self {
            StreamError::Read(quinn::ReadError::ConnectionLost(c))
            | StreamError::Write(quinn::WriteError::ConnectionLost(c)) => Some(c),
            _ => None,
        }
    }

    /// The master's reason when it closed the connection as [`REFUSED`].
    pub fn refusal(&self) -> Option<String> {
        match self.connection_lost()? {
            quinn::ConnectionError::ApplicationClosed(c)
                if c.error_code == quinn::VarInt::from_u32(REFUSED) =>
            {
                Some(String::from_utf8_lossy(&c.reason).into_owned())
            }
            _ => None,
        }
    }
}

/// For a lost connection, why it was lost (reset by peer, closed by peer
/// with its reason, timed out): the part a log reader needs.
fn why_lost(e: &StreamError) -> String {
    e.connection_lost()
        .map_or(String::new(), |c| format!(" ({c})"))
}

/// A framed message stream over a QUIC bidirectional stream.
#[derive(Debug)]
pub struct MessageStream {
    writer: MessageWriter,
    reader: MessageReader,
}

impl MessageStream {
    /// Wrap an opened or accepted bidirectional stream.
    pub fn new(send: quinn::SendStream, recv: quinn::RecvStream) -> Self {
        Self {
            writer: MessageWriter::new(send),
            reader: MessageReader::new(recv),
        }
    }

    /// Send one message.
    pub async fn send(&mut self, msg: &Message) -> Result<(), StreamError> {
        self.writer.send(msg).await.map(|_| ())
    }

    /// Receive the next message. Cancel-safe: bytes already read stay
    /// buffered in the decoder.
    pub async fn recv(&mut self) -> Result<Message, StreamError> {
        self.reader.recv().await
    }

    /// Split into the two halves, to read and write from different tasks.
    pub fn split(self) -> (MessageWriter, MessageReader) {
        (self.writer, self.reader)
    }
}

/// The receiving half: framed, validated messages.
#[derive(Debug)]
pub struct MessageReader {
    recv: quinn::RecvStream,
    decoder: FrameDecoder,
    buf: Vec<u8>,
}

impl MessageReader {
    /// Wrap a receive stream.
    pub fn new(recv: quinn::RecvStream) -> Self {
        Self {
            recv,
            decoder: FrameDecoder::new(MAX_FRAME_LEN),
            buf: vec![0; 64 * 1024],
        }
    }

    /// The next message (cancel-safe).
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
}

/// The sending half.
#[derive(Debug)]
pub struct MessageWriter {
    send: quinn::SendStream,
}

impl MessageWriter {
    /// Wrap a send stream.
    pub fn new(send: quinn::SendStream) -> Self {
        Self { send }
    }

    /// Send one message; returns the bytes written (prefix included).
    pub async fn send(&mut self, msg: &Message) -> Result<usize, StreamError> {
        let frame = encode_frame(msg, MAX_FRAME_LEN)?;
        self.send.write_all(&frame).await?;
        Ok(frame.len())
    }

    /// Finish the stream (the peer reads to the end, then sees it closed).
    pub fn finish(&mut self) {
        let _ = self.send.finish();
    }
}
