//! A socketcand client's end of its link ([`crate::cell::link::FrontLink`]): the frames it
//! sends come in as CAN frames; the bus's frames go out to it as `< frame … >` text, kept
//! during the stream delay after `rawmode` and then in its send buffer, which the runtime
//! writes to the socket as the socket takes it. Its session says which: a client neither
//! streaming nor about to gets no bus frames (the notes on open-source systems kept beside
//! the project, §3.3).

use std::time::Duration;

use canopen::CanFrame;

use crate::can::socketcand::codec::{emit_frame, FRAME_TEXT_MAX};
use crate::can::socketcand::session::Session;
use crate::cell::link::{Addressed, At, FrontLink, SendBuffer};
use crate::cell::wire_faults::{Sender, Verdict};

/// Bytes of bus frames kept for a client while its RAW stream has not started yet.
pub const MAX_HELD: usize = 64 * 1024;

/// A bus frame as a client is sent it: its `< frame … >` text with the time it was on the
/// bus, formatted once for every client of the bus, and the frame it tells (whose identifier
/// a fault may filter on). Sized and kept by value: holding one costs no allocation.
#[derive(Debug, Clone, Copy)]
pub struct FrameText {
    frame: CanFrame,
    len: usize,
    text: [u8; FRAME_TEXT_MAX],
}

impl FrameText {
    /// `frame`, on the bus at `stamp` (since the Unix epoch, or the virtual clock's zero).
    pub fn new(frame: &CanFrame, stamp: Duration) -> Self {
        let mut text = [0u8; FRAME_TEXT_MAX];
        let len = emit_frame(frame, stamp, &mut text);
        FrameText {
            frame: *frame,
            len,
            text,
        }
    }

    pub fn as_bytes(&self) -> &[u8] {
        self.text.get(..self.len).unwrap_or(&[])
    }
}

impl Addressed for FrameText {
    /// A frame seen on the bus, from outside the client's link.
    fn sender(&self) -> Sender {
        Sender::Outside
    }
    fn id(&self) -> u32 {
        self.frame.id
    }
}

/// A socketcand client's session and the bytes on their way to it.
#[derive(Debug)]
pub struct ClientStream {
    pub session: Session,
    /// Frames kept during the stream delay after `rawmode` (at most [`MAX_HELD`] bytes).
    held: Vec<u8>,
    /// Bytes the socket has not taken yet.
    sent: SendBuffer,
}

impl Default for ClientStream {
    fn default() -> Self {
        Self::new()
    }
}

impl ClientStream {
    /// A client just connected: nothing sent yet.
    pub fn new() -> Self {
        ClientStream {
            session: Session::new(),
            held: Vec::new(),
            sent: SendBuffer::with_capacity(1024),
        }
    }

    /// What waits for the socket.
    pub fn sent_mut(&mut self) -> &mut SendBuffer {
        &mut self.sent
    }

    /// The stream has started: the frames kept during its delay go out first.
    pub fn start_stream(&mut self) {
        self.sent.push(&self.held);
        self.held.clear();
    }

    /// The frames kept during the stream delay are skipped (the session said so).
    pub fn skip_held(&mut self) {
        self.held.clear();
    }
}

impl FrontLink for ClientStream {
    type In = CanFrame;
    type Out = FrameText;

    fn receive(&mut self, _: At, _: &CanFrame) -> Verdict {
        Verdict::Pass
    }

    /// Streaming, the text goes to the send buffer; about to stream, it is kept until the
    /// stream starts (as long as [`MAX_HELD`] holds it); otherwise it is not the client's.
    fn transmit(&mut self, _: At, text: &FrameText) -> Verdict {
        let bytes = text.as_bytes();
        if self.session.is_streaming() {
            self.sent.push(bytes);
            Verdict::Pass
        } else if self.session.wants_frames() && self.held.len() + bytes.len() <= MAX_HELD {
            self.held.extend_from_slice(bytes);
            Verdict::Pass
        } else {
            Verdict::Lost
        }
    }

    /// A frame a fault held back was the client's when it crossed: its text goes to the send
    /// buffer as it is.
    fn transmit_held(&mut self, _: At, text: &FrameText) {
        self.sent.push(text.as_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_reaches_a_streaming_client_only() {
        let frame = CanFrame::new(0x181, &[1, 2]).unwrap();
        let text = FrameText::new(&frame, Duration::from_millis(1500));
        assert_eq!(text.as_bytes(), b"< frame 181 1.500000 0102 >");
        assert_eq!(text.id(), 0x181);
        let mut client = ClientStream::new();
        let at = At::on_clock(od::Instant::ZERO);
        assert_eq!(client.transmit(at, &text), Verdict::Lost);
        assert!(client.sent_mut().is_empty());
        client.transmit_held(at, &text);
        assert_eq!(client.sent_mut().bytes(), text.as_bytes());
    }
}
