//! Linux packet sockets: an `AF_PACKET` raw socket bound to one interface and one EtherType,
//! as a device on the wire sees its frames. Elsewhere opening one is unsupported.

use std::io;
use std::os::fd::{BorrowedFd, OwnedFd};

/// `linux/if_packet.h`: packet type of a copy of a frame this host sent.
#[cfg(target_os = "linux")]
const PACKET_OUTGOING: u8 = 4;
/// `linux/if_packet.h`: `enum tpacket_versions`, the ring layout [`RxRing`] reads.
#[cfg(target_os = "linux")]
const TPACKET_V2: libc::c_int = 1;
/// `linux/if_packet.h`: socket option that stops delivery of outgoing copies (Linux 4.20+).
#[cfg(target_os = "linux")]
const PACKET_IGNORE_OUTGOING: libc::c_int = 23;

/// A frame [`recv`] read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Received {
    /// The frame's real length, longer than the buffer when it did not fit.
    pub len: usize,
    /// A copy of a frame this host sent.
    pub outgoing: bool,
    /// When the kernel put it in the receive ring (`tp_sec`, `tp_nsec`: `CLOCK_REALTIME`
    /// since the epoch); none for a frame read with `recvfrom`.
    pub arrived: Option<std::time::Duration>,
}

/// A non-blocking, close-on-exec `AF_PACKET` socket for `ethertype` bound to `interface`,
/// with the outgoing copies switched off where the kernel can (older kernels refuse the
/// option, `ENOPROTOOPT`: [`Received::outgoing`] tells them then). Needs `CAP_NET_RAW`.
#[cfg(target_os = "linux")]
pub fn open(interface: &str, ethertype: u16) -> io::Result<OwnedFd> {
    use std::mem;
    use std::os::fd::AsRawFd;

    let ifindex = super::net_interface::index(interface)?;
    let protocol = ethertype.to_be();
    // SAFETY: plain socket(2) call; `owned` checks the result before taking it.
    let fd = super::fd::owned(unsafe {
        libc::socket(
            libc::AF_PACKET,
            libc::SOCK_RAW | libc::SOCK_NONBLOCK | libc::SOCK_CLOEXEC,
            libc::c_int::from(protocol),
        )
    })?;
    // SAFETY: `sockaddr_ll` is plain old data; all-zero is a valid value.
    let mut addr: libc::sockaddr_ll = unsafe { mem::zeroed() };
    addr.sll_family = libc::AF_PACKET as libc::c_ushort;
    addr.sll_protocol = protocol;
    addr.sll_ifindex = ifindex;
    // SAFETY: `addr` is a properly initialised `sockaddr_ll` and the length matches it.
    let rc = unsafe {
        libc::bind(
            fd.as_raw_fd(),
            (&addr as *const libc::sockaddr_ll).cast::<libc::sockaddr>(),
            mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t,
        )
    };
    super::fd::cvt(rc)?;
    let one: libc::c_int = 1;
    // SAFETY: `one` is a valid c_int for the duration of the call and the length matches.
    let _ = unsafe {
        libc::setsockopt(
            fd.as_raw_fd(),
            libc::SOL_PACKET,
            PACKET_IGNORE_OUTGOING,
            (&one as *const libc::c_int).cast(),
            mem::size_of::<libc::c_int>() as libc::socklen_t,
        )
    };
    Ok(fd)
}

/// One `recvfrom(2)` into `buf`; `WouldBlock` when nothing waits.
#[cfg(target_os = "linux")]
#[inline]
pub fn recv(fd: BorrowedFd<'_>, buf: &mut [u8]) -> io::Result<Received> {
    use std::mem;
    use std::os::fd::AsRawFd;

    // SAFETY: `sockaddr_ll` is plain old data; all-zero is a valid value.
    let mut from: libc::sockaddr_ll = unsafe { mem::zeroed() };
    let mut from_len = mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t;
    // SAFETY: `buf` is valid for writes of `buf.len()` bytes, `from` for `from_len` bytes.
    // MSG_TRUNC makes the call return the real length of a frame longer than `buf`.
    let n = unsafe {
        libc::recvfrom(
            fd.as_raw_fd(),
            buf.as_mut_ptr().cast(),
            buf.len(),
            libc::MSG_TRUNC,
            (&mut from as *mut libc::sockaddr_ll).cast::<libc::sockaddr>(),
            &mut from_len,
        )
    };
    let len = super::fd::cvt_size(n)?;
    Ok(Received {
        len,
        outgoing: from.sll_pkttype == PACKET_OUTGOING,
        arrived: None,
    })
}

/// One `send(2)` on the bound interface (no destination address needed); the bytes taken.
#[cfg(target_os = "linux")]
#[inline]
pub fn send(fd: BorrowedFd<'_>, frame: &[u8]) -> io::Result<usize> {
    use std::os::fd::AsRawFd;

    // SAFETY: `frame` is valid for reads of `frame.len()` bytes; `fd` is open for the borrow.
    super::fd::cvt_size(unsafe {
        libc::send(fd.as_raw_fd(), frame.as_ptr().cast(), frame.len(), 0)
    })
}

/// Bytes of one slot of an [`RxRing`]: a frame header, the sender's address and a frame up
/// to 1984 bytes (an Ethernet frame without FCS is at most 1514).
#[cfg(target_os = "linux")]
const RING_SLOT: usize = 2048;
/// Bytes of one block of an [`RxRing`]: a multiple of any page size Linux has.
#[cfg(target_os = "linux")]
const RING_BLOCK: usize = 64 * 1024;
/// Blocks of an [`RxRing`]: 64 slots, frames a master sends faster than they are read.
#[cfg(target_os = "linux")]
const RING_BLOCKS: usize = 2;

/// A receive ring the kernel shares with the reader (`PACKET_RX_RING`, `TPACKET_V2`): each
/// frame for the socket lands in the next slot, where [`RxRing::recv`] takes it from memory.
/// A frame is read without a system call, and "nothing more waits" is one load where a
/// `recvfrom` would fail with `EAGAIN`: two system calls less per frame on the path of an
/// answer. The socket still wakes a poll for each frame.
#[cfg(target_os = "linux")]
#[derive(Debug)]
pub struct RxRing {
    base: std::ptr::NonNull<u8>,
    next: usize,
}

// SAFETY: the mapping belongs to the ring alone (no copy of the pointer leaves it), so it may
// move to another thread with it; the kernel's side synchronises through `tp_status`.
#[cfg(target_os = "linux")]
unsafe impl Send for RxRing {}

#[cfg(target_os = "linux")]
impl RxRing {
    const SLOTS: usize = RING_BLOCK / RING_SLOT * RING_BLOCKS;
    const BYTES: usize = RING_BLOCK * RING_BLOCKS;

    /// Sets the ring up on the packet socket `fd` and maps it. A frame that came before
    /// waits in the socket's queue, not in the ring: the caller reads those with [`recv`]
    /// once.
    pub fn new(fd: BorrowedFd<'_>) -> io::Result<RxRing> {
        use std::mem;
        use std::os::fd::AsRawFd;

        let version: libc::c_int = TPACKET_V2;
        // SAFETY: `version` is a valid c_int for the duration of the call; the length matches.
        super::fd::cvt(unsafe {
            libc::setsockopt(
                fd.as_raw_fd(),
                libc::SOL_PACKET,
                libc::PACKET_VERSION,
                (&version as *const libc::c_int).cast(),
                mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        })?;
        let req = libc::tpacket_req {
            tp_block_size: RING_BLOCK as libc::c_uint,
            tp_block_nr: RING_BLOCKS as libc::c_uint,
            tp_frame_size: RING_SLOT as libc::c_uint,
            tp_frame_nr: Self::SLOTS as libc::c_uint,
        };
        // SAFETY: `req` is a valid `tpacket_req` for the duration of the call; the length
        // matches.
        super::fd::cvt(unsafe {
            libc::setsockopt(
                fd.as_raw_fd(),
                libc::SOL_PACKET,
                libc::PACKET_RX_RING,
                (&req as *const libc::tpacket_req).cast(),
                mem::size_of::<libc::tpacket_req>() as libc::socklen_t,
            )
        })?;
        // SAFETY: a fresh shared mapping of the ring just set up on `fd`, of its size; the
        // result is checked before use.
        let base = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                Self::BYTES,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED,
                fd.as_raw_fd(),
                0,
            )
        };
        if base == libc::MAP_FAILED {
            return Err(io::Error::last_os_error());
        }
        let base = std::ptr::NonNull::new(base.cast::<u8>())
            .ok_or_else(|| io::Error::other("mmap returned a null ring"))?;
        Ok(RxRing { base, next: 0 })
    }

    /// Whether a frame waits in the next slot: one load from memory, no system call (what a
    /// reader that spins on the ring looks at).
    pub fn ready(&self) -> bool {
        use std::sync::atomic::{AtomicU32, Ordering};

        let offset = self.next % Self::SLOTS * RING_SLOT;
        // SAFETY: `offset` is the start of a slot inside the mapping of `BYTES` bytes.
        let slot = unsafe { self.base.as_ptr().add(offset) };
        // SAFETY: as in `recv`: `tp_status` is an aligned u32 the kernel writes concurrently,
        // read as an atomic only.
        let status = unsafe { &*slot.cast::<AtomicU32>() };
        status.load(Ordering::Acquire) & libc::TP_STATUS_USER != 0
    }

    /// The next frame into `buf` (its first `buf.len()` bytes), or `None` when none waits.
    pub fn recv(&mut self, buf: &mut [u8]) -> Option<Received> {
        use std::sync::atomic::{AtomicU32, Ordering};

        let offset = self.next % Self::SLOTS * RING_SLOT;
        // SAFETY: `offset` is the start of a slot inside the mapping of `BYTES` bytes.
        let slot = unsafe { self.base.as_ptr().add(offset) };
        // SAFETY: `tp_status`, the header's first field, is a 4-byte aligned u32 (slots are
        // 2048-byte aligned in a page-aligned mapping) the kernel writes concurrently: read
        // and written as an atomic only.
        let status = unsafe { &*slot.cast::<AtomicU32>() };
        if status.load(Ordering::Acquire) & libc::TP_STATUS_USER == 0 {
            return None;
        }
        // SAFETY: the slot is the reader's until its status goes back to the kernel; the
        // header lies at its start, aligned.
        let header = unsafe { slot.cast::<libc::tpacket2_hdr>().read() };
        let address_at = (std::mem::size_of::<libc::tpacket2_hdr>() + 15) & !15;
        // SAFETY: the kernel writes the sender's `sockaddr_ll` at TPACKET_ALIGN(header) in
        // the slot; it may be unaligned for the struct.
        let from = unsafe {
            slot.add(address_at)
                .cast::<libc::sockaddr_ll>()
                .read_unaligned()
        };
        let mac = usize::from(header.tp_mac);
        let snap = header.tp_snaplen as usize;
        let len = (header.tp_len as usize).max(snap);
        let copied = if mac.saturating_add(snap) <= RING_SLOT {
            let n = snap.min(buf.len());
            // SAFETY: `mac + n` lies inside the slot, `buf` holds `n` bytes; the two do not
            // overlap (the mapping is not Rust memory).
            unsafe { std::ptr::copy_nonoverlapping(slot.add(mac), buf.as_mut_ptr(), n) };
            snap
        } else {
            usize::MAX
        };
        status.store(libc::TP_STATUS_KERNEL, Ordering::Release);
        self.next = (self.next + 1) % Self::SLOTS;
        Some(Received {
            // A frame the slot cut short is longer than any buffer: it is skipped.
            len: if copied == snap && snap == len {
                len
            } else {
                usize::MAX
            },
            outgoing: from.sll_pkttype == PACKET_OUTGOING,
            arrived: Some(std::time::Duration::new(
                u64::from(header.tp_sec),
                header.tp_nsec,
            )),
        })
    }
}

#[cfg(target_os = "linux")]
impl Drop for RxRing {
    fn drop(&mut self) {
        // SAFETY: the mapping `new` made, of its size; nothing refers to it after the drop.
        unsafe { libc::munmap(self.base.as_ptr().cast(), Self::BYTES) };
    }
}

/// The ring is Linux's: elsewhere none is set up.
#[cfg(not(target_os = "linux"))]
#[derive(Debug)]
pub struct RxRing;

#[cfg(not(target_os = "linux"))]
impl RxRing {
    pub fn new(_fd: BorrowedFd<'_>) -> io::Result<RxRing> {
        Err(io::ErrorKind::Unsupported.into())
    }

    pub fn ready(&self) -> bool {
        false
    }

    pub fn recv(&mut self, _buf: &mut [u8]) -> Option<Received> {
        None
    }
}

/// Packet sockets are Linux's.
#[cfg(not(target_os = "linux"))]
pub fn open(interface: &str, _ethertype: u16) -> io::Result<OwnedFd> {
    Err(io::Error::new(
        io::ErrorKind::Unsupported,
        format!("network interface {interface:?}: raw Ethernet sockets are Linux's"),
    ))
}

/// Packet sockets are Linux's (no socket is ever open to read).
#[cfg(not(target_os = "linux"))]
pub fn recv(_fd: BorrowedFd<'_>, _buf: &mut [u8]) -> io::Result<Received> {
    Err(io::ErrorKind::Unsupported.into())
}

/// Packet sockets are Linux's (no socket is ever open to write).
#[cfg(not(target_os = "linux"))]
pub fn send(_fd: BorrowedFd<'_>, _frame: &[u8]) -> io::Result<usize> {
    Err(io::ErrorKind::Unsupported.into())
}
