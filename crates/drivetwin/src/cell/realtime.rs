//! Real-time scheduling for the threads that play a drive's fieldbus task.

use std::io;

/// `SCHED_FIFO` at `priority` (1…99) for the calling thread. Needs `CAP_SYS_NICE` (root).
pub fn set_fifo_priority(priority: u8) -> io::Result<()> {
    if !(1..=99).contains(&priority) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("real-time priority {priority}: must be 1…99"),
        ));
    }
    crate::sys::sched::set_fifo(priority)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn out_of_range_priority_is_refused() {
        assert_eq!(
            set_fifo_priority(0).unwrap_err().kind(),
            io::ErrorKind::InvalidInput
        );
        assert_eq!(
            set_fifo_priority(100).unwrap_err().kind(),
            io::ErrorKind::InvalidInput
        );
    }
}
