//! Progress of a long command (`scan`, `ecat scan`, `record`, `diff`, `scenario` over several
//! files) as one line on standard error, drawn only for a person at a terminal: nothing when
//! standard error is not a terminal (a pipe, a log file) or when `CI` is set (CI runners that
//! give jobs a pseudo-terminal), so that what scripts and CI logs read stays as it was.
//!
//! Every bar is drawn through one [`MultiProgress`], and the log lines reach standard error
//! through [`log_writer`]: a line is written while the bars are cleared, and the bars are drawn
//! again below it, so that a log line never shares a terminal line with a bar.

use std::io::{self, IsTerminal, Write};
use std::sync::OnceLock;
use std::time::Duration;

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Whether progress is drawn: standard error is a terminal and the environment is no CI
/// (`CI` set to anything but empty, `0` or `false`, as GitHub Actions, GitLab CI and most
/// runners set it).
pub(crate) fn shown(stderr_is_terminal: bool, ci: Option<&str>) -> bool {
    let in_ci = ci.is_some_and(|v| !matches!(v.trim(), "" | "0" | "false"));
    stderr_is_terminal && !in_ci
}

/// The decision for this process.
fn shown_here() -> bool {
    shown(
        std::io::stderr().is_terminal(),
        std::env::var("CI").ok().as_deref(),
    )
}

/// The bars of this process: drawn on standard error where [`shown`] says so, else hidden
/// (then suspending them only runs the write).
fn bars() -> &'static MultiProgress {
    static BARS: OnceLock<MultiProgress> = OnceLock::new();
    BARS.get_or_init(|| {
        MultiProgress::with_draw_target(if shown_here() {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        })
    })
}

/// Writes `bytes` (whole log lines) to `out` while `bars` are cleared, then draws them again.
fn write_between_bars(bars: &MultiProgress, out: &mut impl Write, bytes: &[u8]) -> io::Result<()> {
    bars.suspend(|| {
        out.write_all(bytes)?;
        out.flush()
    })
}

/// Standard error for the log: tracing's formatter writes each event with one `write_all`,
/// which lands between two draws of the bars.
pub(crate) struct LogWriter;

// Standard error is locked only inside the bars' lock, as a bar's own drawing does: the
// other order could deadlock against a spinner's ticking thread.
impl Write for LogWriter {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        write_between_bars(bars(), &mut io::stderr(), buf)?;
        Ok(buf.len())
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        write_between_bars(bars(), &mut io::stderr(), buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        io::stderr().flush()
    }
}

/// The writer `main` gives tracing's formatter.
pub(crate) fn log_writer() -> LogWriter {
    LogWriter
}

/// A bar of `len` steps named `what`, drawn only where [`shown`] says so.
pub(crate) fn bar(len: usize, what: &str) -> ProgressBar {
    if !shown_here() {
        return ProgressBar::hidden();
    }
    let bar = bars().add(ProgressBar::new(u64::try_from(len).unwrap_or(u64::MAX)));
    let style = ProgressStyle::with_template("{msg} {wide_bar} {pos}/{len} [{elapsed}]")
        .unwrap_or_else(|_| ProgressStyle::default_bar());
    bar.set_style(style);
    bar.set_message(what.to_owned());
    bar
}

/// A spinner for a wait whose length is a time, not a count (the answers of a scan), drawn
/// only where [`shown`] says so; it turns by itself until finished.
pub(crate) fn spinner(what: &str) -> ProgressBar {
    if !shown_here() {
        return ProgressBar::hidden();
    }
    let bar = bars().add(ProgressBar::new_spinner());
    let style = ProgressStyle::with_template("{spinner} {msg} [{elapsed}]")
        .unwrap_or_else(|_| ProgressStyle::default_spinner());
    bar.set_style(style);
    bar.set_message(what.to_owned());
    bar.enable_steady_tick(Duration::from_millis(100));
    bar
}

#[cfg(test)]
mod tests {
    use std::io::{self, Write};
    use std::sync::{Arc, Mutex};

    use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, TermLike};

    use super::{shown, write_between_bars};

    /// A terminal and a log sink that note, in one list, what each was asked to do.
    #[derive(Debug, Clone, Default)]
    struct Screen(Arc<Mutex<Vec<String>>>);

    impl Screen {
        fn note(&self, what: String) {
            self.0.lock().unwrap().push(what);
        }
        fn seen(&self) -> Vec<String> {
            self.0.lock().unwrap().clone()
        }
    }

    impl TermLike for Screen {
        fn width(&self) -> u16 {
            80
        }
        fn move_cursor_up(&self, n: usize) -> io::Result<()> {
            self.note(format!("up {n}"));
            Ok(())
        }
        fn move_cursor_down(&self, n: usize) -> io::Result<()> {
            self.note(format!("down {n}"));
            Ok(())
        }
        fn move_cursor_right(&self, _: usize) -> io::Result<()> {
            Ok(())
        }
        fn move_cursor_left(&self, _: usize) -> io::Result<()> {
            Ok(())
        }
        fn write_line(&self, s: &str) -> io::Result<()> {
            self.note(format!("bar {s}"));
            Ok(())
        }
        fn write_str(&self, s: &str) -> io::Result<()> {
            self.note(format!("bar {s}"));
            Ok(())
        }
        fn clear_line(&self) -> io::Result<()> {
            self.note("clear".to_owned());
            Ok(())
        }
        fn flush(&self) -> io::Result<()> {
            Ok(())
        }
    }

    impl Write for Screen {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            self.note(format!("log {}", String::from_utf8_lossy(buf)));
            Ok(buf.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_log_line_is_written_on_a_cleared_line_and_the_bar_drawn_again_below_it() {
        let screen = Screen::default();
        let bars = MultiProgress::with_draw_target(ProgressDrawTarget::term_like(Box::new(
            screen.clone(),
        )));
        let bar = bars.add(ProgressBar::new(10));
        bar.set_message("scenario");
        bar.inc(3);
        bar.tick();
        let before = screen.seen().len();
        assert!(
            screen.seen().iter().any(|s| s.starts_with("bar ")),
            "{:?}",
            screen.seen()
        );

        write_between_bars(&bars, &mut screen.clone(), b"2026 INFO heartbeat lost\n").unwrap();
        let after = screen.seen().split_off(before);
        let log = after.iter().position(|s| s.starts_with("log ")).unwrap();
        assert_eq!(after[log], "log 2026 INFO heartbeat lost\n");
        assert!(
            after[..log].iter().any(|s| s == "clear"),
            "the bar's line is cleared first: {after:?}"
        );
        assert!(
            !after[..log].iter().any(|s| s.starts_with("bar ")),
            "{after:?}"
        );
        assert!(
            after[log + 1..]
                .iter()
                .any(|s| s.starts_with("bar ") && s.contains("3/10")),
            "the bar is drawn again below the line: {after:?}"
        );
    }

    #[test]
    fn with_the_bars_hidden_a_log_line_is_written_as_it_is() {
        let screen = Screen::default();
        let bars = MultiProgress::with_draw_target(ProgressDrawTarget::hidden());
        let _bar = bars.add(ProgressBar::new(10));
        write_between_bars(&bars, &mut screen.clone(), b"line\n").unwrap();
        assert_eq!(screen.seen(), ["log line\n"]);
    }

    #[test]
    fn drawn_only_on_a_terminal_outside_ci() {
        assert!(shown(true, None));
        assert!(!shown(false, None), "a pipe or a log file");
        assert!(!shown(true, Some("true")), "a CI runner's pseudo-terminal");
        assert!(!shown(true, Some("1")));
        assert!(!shown(false, Some("true")));
    }

    #[test]
    fn ci_switched_off_explicitly_still_draws() {
        assert!(shown(true, Some("")));
        assert!(shown(true, Some("0")));
        assert!(shown(true, Some("false")));
    }
}
