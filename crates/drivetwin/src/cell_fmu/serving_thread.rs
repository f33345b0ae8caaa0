//! The thread a front end of the cell FMU serves its sockets on while the importer steps the
//! cell: its own `mio` poll, woken when a step has ended, stopped and joined when the FMU's
//! instance is freed (the front end is dropped).

use std::io::{self, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

use mio::{Poll, Token, Waker};

/// The token of the waker on a serving thread's poll; the front ends number their sockets
/// from 1.
pub const WAKER: Token = Token(0);

/// A serving thread, stopped and joined when dropped.
pub struct ServingThread {
    name: &'static str,
    waker: Arc<Waker>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl ServingThread {
    /// The waker for `poll`, made before the poll moves to the thread.
    pub fn waker(poll: &Poll) -> io::Result<Arc<Waker>> {
        Waker::new(poll.registry(), WAKER).map(Arc::new)
    }

    /// Starts thread `name` running `serve` with the flag that asks it to stop; `waker` is
    /// [`ServingThread::waker`] of the poll `serve` waits on.
    pub fn spawn(
        name: &'static str,
        waker: Arc<Waker>,
        serve: impl FnOnce(Arc<AtomicBool>) + Send + 'static,
    ) -> io::Result<ServingThread> {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let thread = std::thread::Builder::new()
            .name(name.into())
            .spawn(move || serve(flag))?;
        Ok(ServingThread {
            name,
            waker,
            stop,
            thread: Some(thread),
        })
    }

    /// A step has ended: the thread looks at what the step left (frames for the clients,
    /// connections the drives closed).
    pub fn wake(&self) {
        if let Err(e) = self.waker.wake() {
            tracing::warn!(error = %e, thread = self.name, "cell FMU: front end not woken");
        }
    }
}

impl Drop for ServingThread {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        self.wake();
        if let Some(t) = self.thread.take() {
            if t.join().is_err() {
                tracing::error!(
                    thread = self.name,
                    "cell FMU: a front end's thread panicked"
                );
            }
        }
    }
}

/// Writes what a client has not taken yet to its non-blocking `stream`, as far as it takes it;
/// false when the connection failed (closed, or an error other than "would block").
pub fn flush(stream: &mut impl Write, pending: &mut Vec<u8>) -> bool {
    while !pending.is_empty() {
        match stream.write(pending) {
            Ok(0) => return false,
            Ok(n) => {
                pending.drain(..n.min(pending.len()));
            }
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => return true,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(_) => return false,
        }
    }
    true
}
