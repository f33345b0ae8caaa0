//! A drive served over Modbus TCP on a thread of its own, stepped on the real clock
//! (`drivetwin run --modbus-io thread|async`): the device and its server run on one thread,
//! so that a request is read, answered and written by the thread the kernel wakes for it and
//! the device's cycle steps on the same thread; no lock is ever waited for and no work is
//! handed between threads (the request latency a PLC sees).

use std::future::Future;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use tokio::net::TcpListener;

use crate::cell::modbus_device::ModbusDevice;
use crate::modbus_tcp::cycle_server;
use crate::modbus_tcp::server::{lock, serve, ModbusConfig};

/// How the device's thread serves its Modbus connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ServerIo {
    /// The cycle thread reads the connection itself, blocking until a request or the next
    /// cycle ([`crate::modbus_tcp::cycle_server`]): the lowest latency.
    #[default]
    CycleThread,
    /// A task of a single-threaded tokio runtime on that thread ([`crate::modbus_tcp::server`]).
    Async,
}

/// How a device is served.
#[derive(Debug, Clone, Default)]
pub struct ServeOptions {
    pub config: ModbusConfig,
    pub io: ServerIo,
}

/// The device as its thread and its server share it.
type Shared = Arc<Mutex<Box<dyn ModbusDevice>>>;

/// Serves `device` on `listener` and steps it every cycle on the real clock until `shutdown`
/// completes.
pub async fn run(
    listener: TcpListener,
    mut device: Box<dyn ModbusDevice>,
    options: ServeOptions,
    shutdown: impl Future<Output = ()>,
) {
    let ServeOptions { config, io } = options;
    // One cycle before the first client: the registers show the power-on state from the very
    // first request.
    device.step(od::Instant::ZERO);
    let cycle = device.cycle();
    let device: Shared = Arc::new(Mutex::new(device));
    let stop = Arc::new(AtomicBool::new(false));
    let std_listener = match listener.into_std() {
        Ok(l) => l,
        Err(e) => {
            tracing::error!(error = %e, "Modbus listener");
            return;
        }
    };
    let thread_stop = Arc::clone(&stop);
    let name = device_name(&device);
    let runner = std::thread::Builder::new().name(name).spawn(move || {
        let origin = std::time::Instant::now();
        let step = |now: std::time::Instant| {
            let ns =
                u64::try_from(now.saturating_duration_since(origin).as_nanos()).unwrap_or(u64::MAX);
            lock(&device).step(od::Instant::from_nanos(ns));
        };
        match io {
            ServerIo::CycleThread => {
                cycle_server::serve(std_listener, &device, &config, cycle, &thread_stop, step)
            }
            ServerIo::Async => {
                serve_async(std_listener, &device, config, cycle, &thread_stop, step)
            }
        }
    });
    let runner = match runner {
        Ok(t) => t,
        Err(e) => {
            tracing::error!(error = %e, "Modbus device thread");
            return;
        }
    };
    shutdown.await;
    stop.store(true, Ordering::Relaxed);
    let _ = tokio::task::spawn_blocking(move || runner.join()).await;
}

/// The thread's name: the device file's (`cmmo-st`).
fn device_name(device: &Shared) -> String {
    lock(device).description().name.to_owned()
}

/// [`ServerIo::Async`]: the server as a task of a single-threaded runtime, the cycle as its
/// interval timer, until `stop` is set.
fn serve_async(
    listener: std::net::TcpListener,
    device: &Shared,
    config: ModbusConfig,
    cycle: std::time::Duration,
    stop: &AtomicBool,
    mut step: impl FnMut(std::time::Instant),
) {
    let rt = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            tracing::error!(error = %e, "Modbus runtime");
            return;
        }
    };
    rt.block_on(async move {
        let listener = match listener
            .set_nonblocking(true)
            .and_then(|()| TcpListener::from_std(listener))
        {
            Ok(l) => l,
            Err(e) => {
                tracing::error!(error = %e, "Modbus listener");
                return;
            }
        };
        let server = serve(listener, Arc::clone(device), config);
        tokio::pin!(server);
        let mut tick = tokio::time::interval(cycle);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        while !stop.load(Ordering::Relaxed) {
            tokio::select! {
                () = &mut server => break,
                _ = tick.tick() => step(std::time::Instant::now()),
            }
        }
    });
}
