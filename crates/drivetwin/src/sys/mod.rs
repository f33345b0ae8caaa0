//! Platform code: every call into the C library (`libc`, `rustix`) and every `unsafe` block of
//! the crate, behind safe functions that take owned or borrowed descriptors. The rest of the
//! crate denies `unsafe_code` (as smoltcp keeps its OS code in `phy/sys` and ethercrab in
//! `std/`), so a reader looking for what could break memory safety reads this folder only.
//!
//! What only Linux has (SocketCAN, packet sockets, `SCHED_FIFO`, timerfd, `SO_SNDBUF` bounds)
//! is switched here with `cfg(target_os)`: elsewhere the same functions exist and refuse with
//! [`std::io::ErrorKind::Unsupported`], so the transports and the cell loop above need no
//! switch of their own.
//!
//! One file per concern:
//! - [`fd`]: reads, writes and waits on any descriptor; descriptors for tokio;
//! - [`fmu_instance`]: an FMU instance moved to the cell's thread;
//! - [`net_interface`]: network interfaces by name;
//! - [`socketcan`]: `AF_CAN` raw sockets;
//! - [`packet_socket`]: `AF_PACKET` sockets for one EtherType;
//! - [`tcp`]: socket options and non-blocking calls on TCP connections;
//! - [`platform`]: what this platform has (raw Ethernet, SocketCAN);
//! - [`pty`] and [`termios`]: pseudo-terminals and serial devices;
//! - [`sched`]: real-time or batch scheduling of a thread;
//! - [`timer`]: sub-millisecond one-shot timers a poll waits for;
//! - [`thread_usage`]: the CPU time and page faults of the calling thread.

pub mod fd;
pub mod fmu_instance;
pub mod net_interface;
pub mod packet_socket;
pub mod platform;
pub mod pty;
pub mod sched;
pub mod socketcan;
pub mod tcp;
pub mod termios;
pub mod thread_usage;
pub mod timer;
