//! One socketcand client session, sans-IO: what a message from the client does, which frames
//! of the bus the client is sent, and when its timers (stream start, statistics) are due.
//! Time comes in as an argument and effects go out through a callback, so the async server
//! ([`super::server`]) and the cell loop ([`crate::cell_loop`]) run the same rules.
//!
//! Session states follow socketcand (the notes on open-source systems kept beside the project,
//! §3.3): NO_BUS (after `< hi >`; `open` and the `B` / `C` bus configuration commands) → BCM
//! (default after `open`) ⇄ RAW / CONTROL. Only RAW streams bus frames, and only after
//! [`ServerConfig::stream_delay`] from the `< ok >` to `rawmode`. BCM jobs and ISO-TP are answered
//! with `< error ... >`; `send` works in BCM and RAW.

use std::time::{Duration, Instant};

use canopen::CanFrame;

use super::codec::{CodecError, Message, Mode};
use super::server::ServerConfig;

/// Shortest statistics interval honoured (socketcand polls every 10 ms).
const MIN_STATISTICS_INTERVAL: Duration = Duration::from_millis(10);

/// What a message asks of the transport around the session, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Effect {
    /// Write this message on its own (python-can reads each handshake reply with one `recv`).
    Reply(Message),
    /// The client opened the bus: attach it as a node.
    Open,
    /// The client entered RAW mode: frames already waiting for it are dropped.
    SkipPending,
    /// Put this frame on the bus.
    Send(CanFrame),
    /// Close the connection after the replies (the client asked for an unknown bus).
    Close,
}

/// Frame and byte totals of the bus, for CONTROL mode's statistics.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Totals {
    pub frames: u64,
    pub bytes: u64,
}

#[derive(Debug, Clone, Copy)]
struct Statistics {
    period: Duration,
    next: Instant,
}

/// The protocol state of one client.
#[derive(Debug, Default)]
pub struct Session {
    /// `None` until the bus is open (socketcand's NO_BUS state).
    mode: Option<Mode>,
    /// RAW mode: when streaming starts.
    stream_at: Option<Instant>,
    streaming: bool,
    /// CONTROL mode: the statistics timer.
    statistics: Option<Statistics>,
    sent_frames: u64,
    sent_bytes: u64,
}

impl Session {
    /// The greeting a new client is sent.
    pub const HELLO: Message = Message::Hi;

    pub fn new() -> Session {
        Session::default()
    }

    /// Whether the client has opened the bus (it is a node then).
    pub fn is_open(&self) -> bool {
        self.mode.is_some()
    }

    /// Whether bus frames go to the client now.
    pub fn is_streaming(&self) -> bool {
        self.streaming
    }

    /// Whether bus frames are kept for the client (RAW mode, streaming or about to).
    pub fn wants_frames(&self) -> bool {
        self.streaming || self.stream_at.is_some()
    }

    /// A bus frame as the client is sent it, or `None`: socketcand does not forward remote
    /// frames, and a zero-length frame instead would look like a broken heartbeat to
    /// python-canopen (the notes on open-source systems kept beside the project, §3.3).
    pub fn forwards(frame: &CanFrame) -> bool {
        !frame.rtr
    }

    /// The next time [`Session::poll`] has something to do.
    pub fn deadline(&self) -> Option<Instant> {
        match (self.stream_at, self.statistics.map(|s| s.next)) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// Timers: streaming starts, a statistics report is due (`out` gets it).
    pub fn poll(&mut self, now: Instant, bus: Totals, out: &mut dyn FnMut(Effect)) {
        if self.stream_at.is_some_and(|at| now >= at) {
            self.stream_at = None;
            self.streaming = true;
        }
        if let Some(s) = self.statistics.as_mut() {
            if now >= s.next {
                // Missed ticks are not made up (one report, then the next period).
                s.next = now + s.period;
                out(Effect::Reply(Message::Stat {
                    rbytes: bus.bytes.saturating_sub(self.sent_bytes),
                    rpackets: bus.frames.saturating_sub(self.sent_frames),
                    tbytes: self.sent_bytes,
                    tpackets: self.sent_frames,
                }));
            }
        }
    }

    /// One message (or codec error) from the client.
    pub fn on_message(
        &mut self,
        config: &ServerConfig,
        now: Instant,
        message: Result<Message, CodecError>,
        out: &mut dyn FnMut(Effect),
    ) {
        let message = match message {
            Ok(m) => m,
            Err(e) => {
                tracing::debug!(error = %e, "bad message from client");
                out(Effect::Reply(Message::Error(e.to_string())));
                return;
            }
        };
        tracing::trace!(?message, "from client");
        match (self.mode, message) {
            (_, Message::Echo) => out(Effect::Reply(Message::Echo)),
            (None, Message::Open(channel)) => {
                if channel != config.channel {
                    return refuse_channel(config, &channel, out);
                }
                self.mode = Some(Mode::Bcm);
                tracing::debug!(%channel, "bus opened");
                out(Effect::Open);
                out(Effect::Reply(Message::Ok));
            }
            (None, Message::BitTiming { channel, .. })
            | (None, Message::ControlModes { channel, .. }) => {
                if channel != config.channel {
                    return refuse_channel(config, &channel, out);
                }
                // A virtual bus has no bit timing or controller modes to set.
                out(Effect::Reply(Message::Ok));
            }
            (Some(_), Message::Mode(Mode::Isotp)) => {
                out(error("isotp mode not supported"));
            }
            (Some(current), Message::Mode(mode)) => {
                if mode != current {
                    self.enter(mode, out);
                }
                out(Effect::Reply(Message::Ok));
                if mode == Mode::Raw && mode != current {
                    self.stream_at = Some(now + config.stream_delay);
                }
            }
            (Some(Mode::Raw | Mode::Bcm), Message::Send(frame)) => {
                self.sent_frames += 1;
                self.sent_bytes += frame.payload().len() as u64;
                out(Effect::Send(frame));
            }
            (Some(Mode::Control), Message::Statistics { interval_ms }) => {
                self.statistics = (interval_ms > 0).then(|| {
                    let period =
                        Duration::from_millis(u64::from(interval_ms)).max(MIN_STATISTICS_INTERVAL);
                    Statistics {
                        period,
                        next: now + period,
                    }
                });
            }
            (_, Message::Unsupported(command)) => {
                tracing::debug!(command, "unsupported socketcand command");
                out(error("command not supported"));
            }
            (_, other) => {
                tracing::debug!(message = ?other, mode = ?self.mode, "command not valid here");
                out(error("unknown command"));
            }
        }
    }

    /// Leave the current mode for `mode`.
    fn enter(&mut self, mode: Mode, out: &mut dyn FnMut(Effect)) {
        self.mode = Some(mode);
        self.streaming = false;
        self.stream_at = None;
        self.statistics = None;
        if mode == Mode::Raw {
            // Start with the frames sent from now on, not a stale backlog.
            out(Effect::SkipPending);
        }
    }
}

fn error(text: &str) -> Effect {
    Effect::Reply(Message::Error(text.to_owned()))
}

fn refuse_channel(config: &ServerConfig, channel: &str, out: &mut dyn FnMut(Effect)) {
    tracing::info!(requested = %channel, served = %config.channel, "client asked for an unknown bus");
    out(error("could not open bus"));
    out(Effect::Close);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(s: &mut Session, now: Instant, text: &str) -> Vec<Effect> {
        let mut effects = Vec::new();
        let config = ServerConfig::new("vcan0");
        let msg = super::super::codec::parse_body(text.as_bytes());
        s.on_message(&config, now, msg, &mut |e| effects.push(e));
        effects
    }

    #[test]
    fn open_then_raw_streams_after_the_delay() {
        let t0 = Instant::now();
        let mut s = Session::new();
        assert_eq!(
            run(&mut s, t0, "open vcan0"),
            [Effect::Open, Effect::Reply(Message::Ok)]
        );
        assert_eq!(
            run(&mut s, t0, "rawmode"),
            [Effect::SkipPending, Effect::Reply(Message::Ok)]
        );
        assert!(s.wants_frames() && !s.is_streaming());
        assert_eq!(s.deadline(), Some(t0 + ServerConfig::new("x").stream_delay));
        s.poll(t0 + Duration::from_secs(1), Totals::default(), &mut |_| {});
        assert!(s.is_streaming());
        assert_eq!(s.deadline(), None);
    }

    #[test]
    fn unknown_bus_is_refused_and_closed() {
        let mut s = Session::new();
        let effects = run(&mut s, Instant::now(), "open can9");
        assert_eq!(effects.last(), Some(&Effect::Close));
        assert!(!s.is_open());
    }

    #[test]
    fn statistics_count_what_the_client_sent() {
        let t0 = Instant::now();
        let mut s = Session::new();
        run(&mut s, t0, "open vcan0");
        assert!(matches!(
            run(&mut s, t0, "send 601 1 2")[..],
            [Effect::Send(_)]
        ));
        run(&mut s, t0, "controlmode");
        run(&mut s, t0, "statistics 10");
        let mut got = Vec::new();
        let bus = Totals {
            frames: 3,
            bytes: 5,
        };
        s.poll(t0 + Duration::from_millis(10), bus, &mut |e| got.push(e));
        assert_eq!(
            got,
            [Effect::Reply(Message::Stat {
                rbytes: 4,
                rpackets: 2,
                tbytes: 1,
                tpackets: 1
            })]
        );
    }
}
