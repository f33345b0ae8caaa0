//! A device's serial ports and the objects that set them up (device file
//! `[device.serial_ports]`): what a cell reads of a drive's dictionary at power-up to open its
//! lines. The bit-rate objects hold codes of the device's `serial_bit_rate` table
//! ([`crate::description::SerialBitRateCodes`]).

/// One serial port: the interface it is and the objects that set it up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SerialPort {
    /// The interface of the device this port is (`rs232`, `rs485`; one of
    /// [`crate::description::InterfaceOffer::has`]).
    pub interface: &'static str,
    /// The object (sub-index 0) whose code is the port's bit rate from power-up.
    pub bit_rate: u16,
    /// The object (sub-index 0) whose code, once written, is the port's bit rate at once;
    /// `None`: the rate changes only at power-up.
    pub bit_rate_now: Option<u16>,
    /// The object whose value 1 passes on what the drive receives (drives in a ring on one
    /// line); `None`: no ring.
    pub loop_enable: Option<(u16, u8)>,
    /// The object that selects the port's protocol; `None`: the device's telegrams alone.
    pub protocol: Option<ProtocolSelect>,
}

/// The object that selects a serial port's protocol, and its values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProtocolSelect {
    pub object: (u16, u8),
    /// The value for Modbus RTU.
    pub modbus_rtu: u32,
    /// The value for the device's own telegrams.
    pub telegrams: u32,
}

/// The protocol a port speaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SerialProtocol {
    ModbusRtu,
    Telegrams,
}

impl SerialPort {
    /// The port that is interface `interface` among `ports`.
    pub fn find(ports: &'static [SerialPort], interface: &str) -> Option<&'static SerialPort> {
        ports.iter().find(|p| p.interface == interface)
    }

    /// The protocol the port speaks with `value` in its selecting object (`None`: the object
    /// could not be read). A port without one speaks the telegrams; a value that is not the
    /// telegrams' speaks Modbus RTU (the factory value of the one device with such an object,
    /// the Kinco's RS485_Protocol 0).
    pub fn protocol(&self, value: Option<u64>) -> SerialProtocol {
        match self.protocol {
            None => SerialProtocol::Telegrams,
            Some(p) if value == Some(u64::from(p.telegrams)) => SerialProtocol::Telegrams,
            Some(_) => SerialProtocol::ModbusRtu,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RS485: SerialPort = SerialPort {
        interface: "rs485",
        bit_rate: 0x2FE2,
        bit_rate_now: None,
        loop_enable: None,
        protocol: Some(ProtocolSelect {
            object: (0x6510, 0x0C),
            modbus_rtu: 0,
            telegrams: 1,
        }),
    };

    #[test]
    fn the_selecting_value_picks_the_protocol() {
        assert_eq!(RS485.protocol(Some(1)), SerialProtocol::Telegrams);
        assert_eq!(RS485.protocol(Some(0)), SerialProtocol::ModbusRtu);
        assert_eq!(RS485.protocol(Some(7)), SerialProtocol::ModbusRtu);
        assert_eq!(RS485.protocol(None), SerialProtocol::ModbusRtu);
        let rs232 = SerialPort {
            interface: "rs232",
            protocol: None,
            ..RS485
        };
        assert_eq!(rs232.protocol(Some(0)), SerialProtocol::Telegrams);
        let ports: &'static [SerialPort] = &[RS485];
        assert_eq!(SerialPort::find(ports, "rs485"), Some(&RS485));
        assert_eq!(SerialPort::find(ports, "rs232"), None);
    }
}
