//! What this platform has of what the runtime serves: the code above asks here instead of
//! switching on the platform itself, so `cfg(target_os)` stays in `sys`.

/// Why this platform serves no raw Ethernet (the EtherCAT chains' `AF_PACKET` sockets,
/// [`super::packet_socket`]); `None` where it does.
pub fn raw_ethernet_missing() -> Option<&'static str> {
    #[cfg(target_os = "linux")]
    let missing = None;
    #[cfg(not(target_os = "linux"))]
    let missing = Some("EtherCAT (raw Ethernet) needs Linux");
    missing
}

/// Why this platform has no SocketCAN ([`super::socketcan`]); `None` where it has.
pub fn socketcan_missing() -> Option<&'static str> {
    #[cfg(target_os = "linux")]
    let missing = None;
    #[cfg(not(target_os = "linux"))]
    let missing = Some("SocketCAN needs Linux");
    missing
}

#[cfg(test)]
mod tests {
    /// Linux has both; elsewhere each says what is missing.
    #[test]
    fn linux_has_raw_ethernet_and_socketcan() {
        let linux = cfg!(target_os = "linux");
        assert_eq!(super::raw_ethernet_missing().is_none(), linux);
        assert_eq!(super::socketcan_missing().is_none(), linux);
    }
}
