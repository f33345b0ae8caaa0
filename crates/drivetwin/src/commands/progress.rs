//! Progress of a long command (`scan`, `ecat scan`, `record`, `diff`, `scenario` over several
//! files) as one line on standard error, drawn only for a person at a terminal: nothing when
//! standard error is not a terminal (a pipe, a log file) or when `CI` is set (CI runners that
//! give jobs a pseudo-terminal), so that what scripts and CI logs read stays as it was.

use std::io::IsTerminal;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};

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

/// A bar of `len` steps named `what`, drawn only where [`shown`] says so.
pub(crate) fn bar(len: usize, what: &str) -> ProgressBar {
    if !shown_here() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(u64::try_from(len).unwrap_or(u64::MAX));
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
    let bar = ProgressBar::new_spinner();
    let style = ProgressStyle::with_template("{spinner} {msg} [{elapsed}]")
        .unwrap_or_else(|_| ProgressStyle::default_spinner());
    bar.set_style(style);
    bar.set_message(what.to_owned());
    bar.enable_steady_tick(Duration::from_millis(100));
    bar
}

#[cfg(test)]
mod tests {
    use super::shown;

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
