//! The CI terminal of a drive (the CMMP-AS RS232 debug console, manual §3.2.3) as a TCP
//! service: lines of `?XXXXSU` / `=XXXXSU:W…` in, one answer line each out, ended with CR
//! alone as the device ends it ([`drive::vendors::festo_cmmp_as::ci_terminal::ANSWER_END`]).
//! Bound to loopback only: the console writes any object without authentication.
//!
//! The cell loop ([`crate::cell_loop`]) owns the connections: it cuts their lines and
//! answers each from the drive's dictionary on the cell's clock.

use std::net::SocketAddr;

#[derive(Debug, thiserror::Error)]
pub enum ConsoleError {
    #[error("CI terminal address {0:?}: {1}")]
    Address(String, String),
    #[error("CI terminal address {0}: loopback only (the console writes without authentication)")]
    NotLoopback(SocketAddr),
    #[error("CI terminal on {0}: {1}")]
    Bind(String, std::io::Error),
}

/// `addr` as a socket address, if it is a loopback one.
pub fn check_address(addr: &str) -> Result<SocketAddr, ConsoleError> {
    let parsed: SocketAddr = addr
        .parse()
        .map_err(|e: std::net::AddrParseError| ConsoleError::Address(addr.into(), e.to_string()))?;
    if !parsed.ip().is_loopback() {
        return Err(ConsoleError::NotLoopback(parsed));
    }
    Ok(parsed)
}

/// Binds `addr`, which must be a loopback address.
pub fn bind(addr: &str) -> Result<std::net::TcpListener, ConsoleError> {
    std::net::TcpListener::bind(check_address(addr)?)
        .map_err(|e| ConsoleError::Bind(addr.into(), e))
}
