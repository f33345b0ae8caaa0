//! A socketcand-compatible TCP server, so python-can / python-canopen (`interface='socketcand'`)
//! and other socketcand clients can join the in-process [`Bus`](crate::can::bus::Bus).
//!
//! The wire protocol is in the notes on open-source systems kept beside the project, §3.3.
//! [`codec`] is the pure, I/O-free part (framing, parsing, formatting); [`server`] is the async TCP
//! side.

pub mod client_link;
pub mod codec;
pub mod join;
pub mod server;
pub mod session;

pub use codec::{CodecError, Decoder, Message, Mode, MAX_MESSAGE_LEN};
pub use server::{handle_client, serve, serve_with, ServerConfig, SessionError, DEFAULT_PORT};
