//! What a load FMU last said through its logger, for the error that stops the cell.
//!
//! The `fmi` crate's logger callback (FMI 3.0 §2.3.1 `fmi3LogMessageCallback`, FMI 2.0 §2.1.5
//! `logger`) hands every message of an FMU to the `log` crate, with module path `fmu` and no
//! word of which instance spoke. An FMU calls it from inside the call that fails, on the
//! thread that made the call, so the last warning or error said on that thread is the one of
//! the FMU that thread is stepping. [`install`] puts [`FmuLog`] in as the process's `log`
//! logger: it keeps that message and passes every record on to `tracing` as
//! `tracing_subscriber`'s own bridge does.

use std::cell::RefCell;

use log::{Level, Log, Metadata, Record};

/// The module path the `fmi` crate gives an FMU's messages.
const FMU: &str = "fmu";

thread_local! {
    static LAST: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// The process's `log` logger: an FMU's warnings and errors kept per thread, every record to
/// `tracing`.
pub struct FmuLog {
    tracing: tracing_log::LogTracer,
}

impl Log for FmuLog {
    fn enabled(&self, metadata: &Metadata<'_>) -> bool {
        self.tracing.enabled(metadata)
    }

    fn log(&self, record: &Record<'_>) {
        if record.module_path() == Some(FMU) && record.level() <= Level::Warn {
            let message = record.args().to_string();
            LAST.with(|l| *l.borrow_mut() = Some(message));
        }
        self.tracing.log(record);
    }

    fn flush(&self) {
        self.tracing.flush();
    }
}

/// Makes [`FmuLog`] the process's `log` logger; `false` when one is set already (its FMU
/// messages are not kept then, and errors say only the status).
pub fn install() -> bool {
    let installed = log::set_boxed_logger(Box::new(FmuLog {
        tracing: tracing_log::LogTracer::new(),
    }))
    .is_ok();
    if installed {
        log::set_max_level(log::LevelFilter::Trace);
    }
    installed
}

/// Forgets what an FMU said on this thread (before a call whose failure is to be explained).
pub fn clear() {
    LAST.with(|l| {
        if let Ok(mut l) = l.try_borrow_mut() {
            *l = None;
        }
    });
}

/// The last warning or error an FMU said on this thread, taken.
pub fn take() -> Option<String> {
    LAST.with(|l| l.try_borrow_mut().ok().and_then(|mut l| l.take()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_fmus_error_is_kept_for_its_thread_and_taken_once() {
        let log = FmuLog {
            tracing: tracing_log::LogTracer::new(),
        };
        clear();
        log.log(
            &Record::builder()
                .args(format_args!("mass -1 kg must be positive"))
                .level(Level::Error)
                .module_path(Some(FMU))
                .target("logAll")
                .build(),
        );
        // Another module's record and an FMU's information are not kept.
        log.log(
            &Record::builder()
                .args(format_args!("other"))
                .level(Level::Error)
                .module_path(Some("somewhere"))
                .build(),
        );
        log.log(
            &Record::builder()
                .args(format_args!("info"))
                .level(Level::Info)
                .module_path(Some(FMU))
                .build(),
        );
        let other = std::thread::spawn(take).join().unwrap();
        assert_eq!(other, None);
        assert_eq!(take().as_deref(), Some("mass -1 kg must be positive"));
        assert_eq!(take(), None);
    }
}
