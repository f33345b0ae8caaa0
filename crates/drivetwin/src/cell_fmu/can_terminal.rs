//! The cell FMU's FMI-LS-BUS CAN terminals (FMI-LS-BUS 1.0, Network Abstraction §4): one
//! Bus Terminal per CAN bus of the cell, through which a PLC or master FMU on the same bus
//! talks to the drives inside the co-simulation.
//!
//! Each terminal has the four members the standard names (§4.2): `Rx_Data` (Binary input,
//! clocked by `Rx_Clock`, a `triggered` input Clock) carries the operations the importer hands
//! the FMU; `Tx_Data` (Binary output, clocked by `Tx_Clock`) the operations the FMU sends.
//!
//! **Decision:** `Tx_Clock` is a `triggered` output Clock (§4.2.1.2): its ticks are the ends of
//! `fmi3DoStep`, never an early return, so the Bus Communication Points are the importer's
//! communication points. A frame a drive sends crosses the cell's bus at the time the bus
//! model gives it (arbitration, bit time); the step in which it crosses ends with
//! `eventHandlingNeeded`, and in the Event Mode that follows `Tx_Clock` ticks and `Tx_Data`
//! holds a CAN Transmit per frame, in the order they crossed. An importer that steps in
//! intervals of the bit time sees each frame at its time; one that steps in milliseconds sees
//! the frames of the millisecond at its end (§2 "Common Concepts": a Low-Cut FMU buffers the
//! operations of a step). A time-based (countdown) `Tx_Clock` would need the clock interval
//! functions, which `fmi-export` does not implement.
//!
//! What the terminal does with the operations it receives (§4.4.1.2):
//!
//! - CAN Transmit: the frame goes onto the cell's bus at the FMU's time (the time of the
//!   Event Mode in which `Rx_Clock` ticked), from outside the cell's drives, and crosses it as
//!   any frame does;
//! - Configuration `CAN_BAUDRATE`: the master's bit rate. **Decision:** a rate other than the
//!   bus's (`bitrate` of the cell file, or its drives' switches) cannot be heard on that bus:
//!   the master's frames are not put on it and each is answered with a Bus Error (`BIT_ERROR`,
//!   primary, `Is Sender`), which a transmitter at the wrong rate reads back; the instant bus
//!   takes any rate. `ARBITRATION_LOST_BEHAVIOR` (§4.4.1.4 "Arbitration"): with
//!   `BUFFER_AND_RETRANSMIT` (the default) a frame of the master's that cannot start at once
//!   (the bus busy, or a drive's frame waiting that wins the arbitration) waits in the bus
//!   model and is sent when the bus is free; with `DISCARD_AND_NOTIFY` it is discarded and
//!   answered with Arbitration Lost. CAN FD / CAN XL baud
//!   rates are ignored (the drives are classic CAN nodes);
//! - CAN FD and CAN XL Transmit: answered with a Bus Error (`FORM_ERROR`, primary, `Is
//!   Sender`): a classic CAN controller reads an FD or XL frame as a form error;
//! - an operation that cannot be read: answered with a Format Error carrying its bytes;
//! - Confirm, Arbitration Lost, Bus Error, Status, Wakeup: taken and ignored (the cell is no
//!   participant they could concern).
//!
//! What the master hears of its own frames (§4.4.1.2): once a frame has crossed the bus (at
//! its end of frame in the bus model), Confirm with its ID when a drive on the bus received
//! it, a Bus Error `ACK_ERROR` (primary, `Is Sender`) when none did; Arbitration Lost as
//! above; the Bus Errors of a wrong bit rate and of FD / XL frames. Confirm and the
//! acknowledgement's Bus Error come only when the importer sets the cell's structural
//! parameter `org.fmi_standard.fmi_ls_bus.Can_BusNotifications` (§4.4.1.3; false by default,
//! the standard's fire-and-forget). **Decision:** the importer sets that parameter alike on
//! the Network FMUs of one bus, so true on the cell says the master takes notifications, and
//! the cell, whose bus model carries the master's frames, sends them as a Bus Simulation
//! would. Arbitration Lost comes whenever the master configured `DISCARD_AND_NOTIFY`: it asked
//! for it by name, and a discarded frame nobody is told of would vanish.

use std::fmt::Write;
use std::time::Duration;

use canopen::CanFrame;

use super::instance::CellInstance;
use super::ls_bus::{self, Configuration, ErrorCode, ErrorFlag, Operation};
use super::CellFmuError;

/// The value reference of the first terminal's first member. The terminals' value
/// references are their own range, apart from the drives' table, so that variables added to
/// that table move no terminal.
pub const FIRST_VALUE_REFERENCE: u32 = 0x4C53_0000;

/// The value reference of `org.fmi_standard.fmi_ls_bus.Can_BusNotifications` (§4.4.1.3,
/// "Bus Notification Parameter"), in the terminals' range after every terminal's members.
pub const BUS_NOTIFICATIONS_VALUE_REFERENCE: u32 = FIRST_VALUE_REFERENCE + 0xFFFF;

/// The structural parameter's name, as the standard gives it.
pub const BUS_NOTIFICATIONS: &str = "org.fmi_standard.fmi_ls_bus.Can_BusNotifications";

/// The members of a Bus Terminal, in value-reference order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Member {
    RxData,
    RxClock,
    TxData,
    TxClock,
}

impl Member {
    const ALL: [Member; 4] = [
        Member::RxData,
        Member::RxClock,
        Member::TxData,
        Member::TxClock,
    ];

    /// The standard's `memberName` (§4.3.1).
    pub fn name(self) -> &'static str {
        match self {
            Member::RxData => "Rx_Data",
            Member::RxClock => "Rx_Clock",
            Member::TxData => "Tx_Data",
            Member::TxClock => "Tx_Clock",
        }
    }
}

/// The value reference of member `m` of bus `bus`'s terminal.
pub fn value_reference(bus: usize, m: Member) -> u32 {
    let index = Member::ALL.iter().position(|x| *x == m).unwrap_or(0);
    let bus = u32::try_from(bus).unwrap_or(0);
    FIRST_VALUE_REFERENCE + 4 * bus + u32::try_from(index).unwrap_or(0)
}

/// The terminal and member of value reference `vr`.
pub fn find(vr: u32, buses: usize) -> Option<(usize, Member)> {
    let i = vr.checked_sub(FIRST_VALUE_REFERENCE)?;
    let bus = usize::try_from(i / 4).ok()?;
    let m = *Member::ALL.get(usize::try_from(i % 4).ok()?)?;
    (bus < buses).then_some((bus, m))
}

/// The terminal's name, and the prefix of its variables' names: `can0`, `can1`, … in the
/// order of the cell file's buses.
pub fn terminal_name(bus: usize) -> String {
    format!("can{bus}")
}

/// One bus's terminal.
#[derive(Debug, Default)]
pub struct CanTerminal {
    /// The bus's bit rate (none: the instant bus).
    bitrate: Option<u32>,
    /// The master's bit rate, as its last `CAN_BAUDRATE` Configuration said.
    master_bitrate: Option<u32>,
    /// What becomes of the master's frame that cannot go on the bus at once (its last
    /// `ARBITRATION_LOST_BEHAVIOR` Configuration; none: `BUFFER_AND_RETRANSMIT`).
    arbitration: Option<ls_bus::ArbitrationLostBehavior>,
    /// The master's frames on the bus that have not crossed it yet, in the order sent.
    on_bus: std::collections::VecDeque<CanFrame>,
    /// `Can_BusNotifications`: the master takes Confirm and the acknowledgement's Bus Error.
    notifications: bool,
    rx_data: Vec<u8>,
    rx_clock: bool,
    /// Frames from Rx_Data, for the bus at the next step's start.
    to_bus: Vec<CanFrame>,
    /// Operations for the next Tx_Clock tick.
    tx_next: Vec<u8>,
    /// Tx_Data as the importer reads it (the operations of the last tick).
    tx_data: Vec<u8>,
    tx_clock: bool,
}

impl CanTerminal {
    pub fn new(bitrate: Option<u32>) -> CanTerminal {
        CanTerminal {
            bitrate,
            ..CanTerminal::default()
        }
    }

    pub fn set_rx_data(&mut self, bytes: &[u8]) {
        self.rx_data.clear();
        self.rx_data.extend_from_slice(bytes);
    }

    pub fn rx_data(&self) -> &[u8] {
        &self.rx_data
    }

    pub fn set_rx_clock(&mut self, tick: bool) {
        self.rx_clock |= tick;
    }

    pub fn tx_data(&self) -> &[u8] {
        &self.tx_data
    }

    /// `Tx_Clock` as `fmi3GetClock` reads it: a tick is read once (FMI 3.0 §2.2.8.3).
    pub fn take_tx_clock(&mut self) -> bool {
        std::mem::take(&mut self.tx_clock)
    }

    /// Whether operations wait for a `Tx_Clock` tick.
    pub fn has_tx(&self) -> bool {
        !self.tx_next.is_empty()
    }

    /// `fmi3UpdateDiscreteStates`: the operations of a ticked `Rx_Clock` are taken; answers
    /// (Format Error, Bus Error) tick `Tx_Clock` at once.
    pub fn update(&mut self) {
        self.accept_rx();
        self.tick();
    }

    /// The operations of a ticked `Rx_Clock`, once.
    fn accept_rx(&mut self) {
        if std::mem::take(&mut self.rx_clock) {
            // (taken and given back emptied: its room stays for the next Rx_Data)
            let mut rx = std::mem::take(&mut self.rx_data);
            self.receive(&rx);
            rx.clear();
            self.rx_data = rx;
        }
    }

    /// A step begins: last tick's Tx_Data is gone, and the frames received go to the bus (a
    /// tick of `Rx_Clock` not yet taken by `fmi3UpdateDiscreteStates` is taken now).
    pub fn take_to_bus(&mut self) -> Vec<CanFrame> {
        let mut frames = Vec::new();
        self.take_to_bus_into(&mut frames);
        frames
    }

    /// [`CanTerminal::take_to_bus`] into `frames` (emptied first): the two buffers trade
    /// places, so a step that reuses `frames` allocates nothing.
    pub fn take_to_bus_into(&mut self, frames: &mut Vec<CanFrame>) {
        self.accept_rx();
        self.tx_data.clear();
        frames.clear();
        std::mem::swap(frames, &mut self.to_bus);
    }

    /// Whether `Tx_Clock` has ticked and not been read.
    pub fn tx_ticked(&self) -> bool {
        self.tx_clock
    }

    /// A frame crossed this terminal's bus at `at` (the end of its transmission).
    pub fn crossed(&mut self, _at: Duration, frame: &CanFrame) {
        // A remote frame's Data Length is the length it requests (its DLC).
        const REQUESTED: [u8; 8] = [0; 8];
        let data = if frame.rtr {
            REQUESTED.get(..usize::from(frame.len)).unwrap_or(&[])
        } else {
            frame.payload()
        };
        self.push(Operation::CanTransmit {
            id: frame.id,
            ide: frame.extended,
            rtr: frame.rtr,
            data,
        });
    }

    /// Whether a frame of the master's that cannot go on the bus at once is discarded and
    /// answered with Arbitration Lost (`DISCARD_AND_NOTIFY`, §4.4.1.2.6), not kept for the
    /// bus to send when it is free (`BUFFER_AND_RETRANSMIT`, the default).
    pub fn discards_on_arbitration_lost(&self) -> bool {
        self.arbitration == Some(ls_bus::ArbitrationLostBehavior::DiscardAndNotify)
    }

    /// The master's `frame` could not go on the bus at once and is discarded: Arbitration
    /// Lost (0x30) with its ID, in the same Event Mode's `Tx_Clock` tick.
    pub fn arbitration_lost(&mut self, frame: &CanFrame) {
        self.push(Operation::ArbitrationLost { id: frame.id });
    }

    /// `Can_BusNotifications` as the importer set it (false by default, §4.4.1.3).
    pub fn set_notifications(&mut self, on: bool) {
        self.notifications = on;
    }

    pub fn notifications(&self) -> bool {
        self.notifications
    }

    /// The master's `frame` went on the bus: with notifications, it is confirmed when it
    /// has crossed.
    pub fn sent(&mut self, frame: CanFrame) {
        if self.notifications {
            self.on_bus.push_back(frame);
        }
    }

    /// A frame from outside the drives crossed the bus; when it is the master's, the master
    /// is told: Confirm (0x20) when a drive received it (its acknowledgement, §4.4.1.2.2),
    /// else a Bus Error `ACK_ERROR` (primary, `Is Sender`): no node acknowledged it. A frame
    /// from another outside sender (a socketcand client) is not the master's business.
    pub fn outside_crossed(&mut self, frame: &CanFrame, acknowledged: bool) {
        let Some(i) = self.on_bus.iter().position(|f| f == frame) else {
            return;
        };
        self.on_bus.remove(i);
        if acknowledged {
            self.push(Operation::Confirm { id: frame.id });
        } else {
            self.bus_error(frame.id, ErrorCode::AckError);
        }
    }

    /// The step ends: the operations gathered during it tick `Tx_Clock`.
    pub fn tick(&mut self) {
        if !self.tx_next.is_empty() {
            // (the two lists trade places, so neither is made anew)
            std::mem::swap(&mut self.tx_data, &mut self.tx_next);
            self.tx_next.clear();
            self.tx_clock = true;
        }
    }

    fn push(&mut self, op: Operation<'_>) {
        if let Err(e) = op.emit(&mut self.tx_next) {
            tracing::warn!("LS-BUS: {e}");
        }
    }

    fn receive(&mut self, rx: &[u8]) {
        for op in ls_bus::parse(rx) {
            match op {
                Err(m) => self.push(Operation::FormatError { data: m.bytes }),
                Ok(Operation::CanTransmit { id, ide, rtr, data }) => {
                    let wrong_rate = match (self.bitrate, self.master_bitrate) {
                        (Some(bus), Some(master)) => bus != master,
                        _ => false,
                    };
                    let frame = if rtr {
                        u16::try_from(id)
                            .ok()
                            .filter(|_| !ide)
                            .and_then(|id| u8::try_from(data.len()).ok().map(|n| (id, n)))
                            .map(|(id, n)| CanFrame::remote(id, n))
                            .ok_or(())
                    } else {
                        CanFrame::with_id(id, ide, data).map_err(drop)
                    };
                    match frame {
                        Ok(f) if !wrong_rate => self.to_bus.push(f),
                        Ok(_) => self.bus_error(id, ErrorCode::BitError),
                        Err(()) => self.push(Operation::FormatError {
                            data: rx_op(rx, id),
                        }),
                    }
                }
                Ok(Operation::CanFdTransmit { id, .. } | Operation::CanXlTransmit { id, .. }) => {
                    self.bus_error(id, ErrorCode::FormError);
                }
                Ok(Operation::Configuration(c)) => match c {
                    Configuration::CanBaudRate(r) => {
                        if self.bitrate.is_some_and(|b| b != r) {
                            tracing::warn!(
                                "LS-BUS: the master is configured for {r} bit/s, the bus runs at {} bit/s: its frames are bus errors",
                                self.bitrate.unwrap_or(0)
                            );
                        }
                        self.master_bitrate = Some(r);
                    }
                    Configuration::ArbitrationLostBehavior(b) => self.arbitration = Some(b),
                    _ => {}
                },
                Ok(_) => {}
            }
        }
    }

    fn bus_error(&mut self, id: u32, code: ErrorCode) {
        self.push(Operation::BusError {
            id,
            code,
            flag: ErrorFlag::Primary,
            is_sender: true,
        });
    }
}

/// The bytes of the CAN Transmit with `id` in `rx` (for a Format Error), or all of `rx`.
fn rx_op(rx: &[u8], id: u32) -> &[u8] {
    let mut rest = rx;
    while let (Some(h), Some(l)) = (rest.get(..4), rest.get(4..8)) {
        let len = l
            .try_into()
            .map(u32::from_le_bytes)
            .ok()
            .and_then(|n| usize::try_from(n).ok())
            .unwrap_or(0);
        let (Some(op), Some(next)) = (rest.get(..len), rest.get(len..)) else {
            break;
        };
        if h == ls_bus::op_code::CAN_TRANSMIT.to_le_bytes()
            && op.get(8..12) == Some(&id.to_le_bytes()[..])
        {
            return op;
        }
        if len == 0 {
            break;
        }
        rest = next;
    }
    rx
}

impl CellInstance {
    /// What crossed the buses during a step goes to their terminals, which tick: the drives'
    /// frames (`frames`) and the ends of the master's own (`outside`: bus, end of frame,
    /// frame, acknowledged), in the order of their times.
    pub(super) fn terminals_saw(
        terminals: &mut [CanTerminal],
        frames: &[(usize, Duration, CanFrame)],
        outside: &[(usize, Duration, CanFrame, bool)],
    ) {
        let mut o = outside.iter().peekable();
        for (bus, at, frame) in frames {
            while let Some((b, _, f, acked)) = o.next_if(|(_, end, _, _)| end <= at) {
                if let Some(t) = terminals.get_mut(*b) {
                    t.outside_crossed(f, *acked);
                }
            }
            if let Some(t) = terminals.get_mut(*bus) {
                t.crossed(*at, frame);
            }
        }
        for (b, _, f, acked) in o {
            if let Some(t) = terminals.get_mut(*b) {
                t.outside_crossed(f, *acked);
            }
        }
        for t in terminals {
            t.tick();
        }
    }

    fn terminal(&self, vr: u32) -> Result<(&CanTerminal, Member), CellFmuError> {
        find(vr, self.terminals.len())
            .and_then(|(b, m)| self.terminals.get(b).map(|t| (t, m)))
            .ok_or(CellFmuError::UnknownVariable(vr))
    }

    fn terminal_mut(&mut self, vr: u32) -> Result<(&mut CanTerminal, Member), CellFmuError> {
        let n = self.terminals.len();
        find(vr, n)
            .and_then(|(b, m)| self.terminals.get_mut(b).map(|t| (t, m)))
            .ok_or(CellFmuError::UnknownVariable(vr))
    }

    /// `fmi3GetBinary`: `Rx_Data` as set, `Tx_Data` of the last `Tx_Clock` tick.
    pub fn get_binary(&self, vr: u32) -> Result<&[u8], CellFmuError> {
        match self.terminal(vr)? {
            (t, Member::RxData) => Ok(t.rx_data()),
            (t, Member::TxData) => Ok(t.tx_data()),
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    /// `fmi3SetBinary`: `Rx_Data`.
    pub fn set_binary(&mut self, vr: u32, bytes: &[u8]) -> Result<(), CellFmuError> {
        match self.terminal_mut(vr)? {
            (t, Member::RxData) => {
                t.set_rx_data(bytes);
                Ok(())
            }
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    /// `Can_BusNotifications` (a Boolean structural parameter), if `vr` is it.
    pub(super) fn set_bus_notifications(&mut self, vr: u32, on: bool) -> bool {
        if vr != BUS_NOTIFICATIONS_VALUE_REFERENCE {
            return false;
        }
        for t in &mut self.terminals {
            t.set_notifications(on);
        }
        true
    }

    pub(super) fn bus_notifications(&self, vr: u32) -> Option<bool> {
        (vr == BUS_NOTIFICATIONS_VALUE_REFERENCE)
            .then(|| self.terminals.iter().any(CanTerminal::notifications))
    }

    /// `fmi3GetClock`: `Tx_Clock`, reset by the read.
    pub fn get_clock(&mut self, vr: u32) -> Result<bool, CellFmuError> {
        match self.terminal_mut(vr)? {
            (t, Member::TxClock) => Ok(t.take_tx_clock()),
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    /// `fmi3SetClock`: `Rx_Clock`.
    pub fn set_clock(&mut self, vr: u32, tick: bool) -> Result<(), CellFmuError> {
        match self.terminal_mut(vr)? {
            (t, Member::RxClock) => {
                t.set_rx_clock(tick);
                Ok(())
            }
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    /// `fmi3UpdateDiscreteStates`: the terminals take what `Rx_Clock` brought.
    pub fn update_discrete_states(&mut self) {
        for t in &mut self.terminals {
            t.update();
        }
    }

    /// Whether a `Tx_Clock` ticked (`fmi3DoStep`'s `eventHandlingNeeded`).
    pub fn event_needed(&self) -> bool {
        self.terminals.iter().any(CanTerminal::tx_ticked)
    }

    /// How many CAN buses (terminals) the cell has.
    pub fn buses(&self) -> usize {
        self.terminals.len()
    }
}

/// `terminalsAndIcons/terminalsAndIcons.xml` (FMI 3.0 §2.4.9) with one Bus Terminal per bus
/// (§4.3.1: `terminalKind` `org.fmi-ls-bus.network-terminal`, `matchingRule`
/// `org.fmi-ls-bus.transceiver`, the four members as `signal`s).
pub fn terminals_and_icons(buses: usize) -> String {
    let mut x = String::new();
    x.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    x.push_str("<fmiTerminalsAndIcons fmiVersion=\"3.0\">\n  <Terminals>\n");
    for b in 0..buses {
        let name = terminal_name(b);
        let _ = writeln!(
            x,
            r#"    <Terminal terminalKind="org.fmi-ls-bus.network-terminal" name="{name}" matchingRule="org.fmi-ls-bus.transceiver" description="CAN bus {b} of the cell">"#
        );
        for m in Member::ALL {
            let _ = writeln!(
                x,
                r#"      <TerminalMemberVariable variableKind="signal" variableName="{name}.{0}" memberName="{0}"/>"#,
                m.name()
            );
        }
        x.push_str("    </Terminal>\n");
    }
    x.push_str("  </Terminals>\n</fmiTerminalsAndIcons>\n");
    x
}

/// Where the layered standard's manifest goes in the FMU (FMI 3.0 §2.5.1: `extra/<name>/`).
pub const MANIFEST_PATH: &str = "extra/org.fmi-standard.fmi-ls-bus/fmi-ls-manifest.xml";

/// The manifest (§1 and `fmi3LayeredStandardBusManifest.xsd`): FMI-LS-BUS 1.0.0, not a Bus
/// Simulation FMU (the cell is a network participant whose bus model times its own frames).
pub const MANIFEST: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<fmiLayeredStandardManifest
    xmlns:fmi-ls="http://fmi-standard.org/fmi-ls-manifest"
    fmi-ls:fmi-ls-name="org.fmi-standard.fmi-ls-bus"
    fmi-ls:fmi-ls-version="1.0.0"
    fmi-ls:fmi-ls-description="Layered Standard for the simulation of bus communication on a Physical Signal Abstraction or Network Abstraction based level."
    isBusSimulationFMU="false"/>
"#;

#[cfg(test)]
mod tests {
    use super::*;

    fn transmit(id: u32, data: &[u8]) -> Vec<u8> {
        let mut v = Vec::new();
        Operation::CanTransmit {
            id,
            ide: false,
            rtr: false,
            data,
        }
        .emit(&mut v)
        .unwrap();
        v
    }

    #[test]
    fn value_references_find_their_member() {
        for b in 0..3 {
            for m in Member::ALL {
                assert_eq!(find(value_reference(b, m), 3), Some((b, m)));
            }
        }
        assert_eq!(find(value_reference(3, Member::RxData), 3), None);
        assert_eq!(find(1, 3), None);
    }

    #[test]
    fn a_transmit_on_rx_goes_to_the_bus_and_a_crossed_frame_ticks_tx() {
        let mut t = CanTerminal::new(Some(125_000));
        t.set_rx_data(&transmit(0x601, &[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]));
        t.update();
        // Nothing is on Rx until the clock ticks.
        assert!(t.take_to_bus().is_empty());
        t.set_rx_clock(true);
        t.update();
        assert!(!t.take_tx_clock());
        let frames = t.take_to_bus();
        assert_eq!(
            frames,
            [CanFrame::new(0x601, &[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]).unwrap()]
        );
        let answer = CanFrame::new(0x581, &[0x43, 0x18, 0x10, 0x01, 0x1D, 0, 0, 0]).unwrap();
        t.crossed(Duration::from_micros(1792), &answer);
        assert!(t.has_tx());
        t.tick();
        assert!(t.take_tx_clock());
        assert!(!t.take_tx_clock());
        assert_eq!(
            t.tx_data(),
            transmit(0x581, &[0x43, 0x18, 0x10, 0x01, 0x1D, 0, 0, 0])
        );
        // The next step clears it.
        t.take_to_bus();
        assert!(t.tx_data().is_empty());
    }

    #[test]
    fn a_master_at_another_bit_rate_gets_bus_errors_and_reaches_no_drive() {
        let mut t = CanTerminal::new(Some(125_000));
        let mut rx = Vec::new();
        Operation::Configuration(Configuration::CanBaudRate(500_000))
            .emit(&mut rx)
            .unwrap();
        rx.extend(transmit(0x601, &[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]));
        t.set_rx_data(&rx);
        t.set_rx_clock(true);
        t.update();
        assert!(t.take_to_bus().is_empty());
        // `take_to_bus` starts a step: the answer was read in the Event Mode before it.
        let mut t2 = CanTerminal::new(Some(125_000));
        t2.set_rx_data(&rx);
        t2.set_rx_clock(true);
        t2.update();
        assert!(t2.take_tx_clock());
        let ops: Vec<_> = ls_bus::parse(t2.tx_data()).collect();
        assert_eq!(
            ops,
            [Ok(Operation::BusError {
                id: 0x601,
                code: ErrorCode::BitError,
                flag: ErrorFlag::Primary,
                is_sender: true
            })]
        );
        // The bus's own rate is heard.
        let mut t3 = CanTerminal::new(Some(125_000));
        let mut rx = Vec::new();
        Operation::Configuration(Configuration::CanBaudRate(125_000))
            .emit(&mut rx)
            .unwrap();
        rx.extend(transmit(0x601, &[1]));
        t3.set_rx_data(&rx);
        t3.set_rx_clock(true);
        t3.update();
        assert_eq!(t3.take_to_bus().len(), 1);
    }

    /// The master's frame once it has crossed: a drive received it, Confirm (0x20, Total
    /// Length 12: OP Code, Length, ID, FMI-LS-BUS §4.4.1.2.2); none did, Bus Error (0x31,
    /// Length 15: ID, Error Code 0x05 ACK_ERROR, Error Flag 0x01 primary, Is Sender 0x01).
    #[test]
    fn the_masters_frame_is_confirmed_when_a_drive_received_it_and_else_an_ack_error() {
        let mut t = CanTerminal::new(Some(125_000));
        // Fire-and-forget by default: nothing comes back.
        let f = CanFrame::new(0x601, &[1]).unwrap();
        t.sent(f);
        t.outside_crossed(&f, true);
        assert!(!t.has_tx());
        t.set_notifications(true);
        t.set_rx_data(&transmit(0x601, &[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]));
        t.set_rx_clock(true);
        t.update();
        let [frame] = t.take_to_bus()[..] else {
            panic!("one frame")
        };
        t.sent(frame);
        // A frame of another outside sender (a socketcand client) is not confirmed.
        t.outside_crossed(&CanFrame::new(0x602, &[1]).unwrap(), true);
        assert!(!t.has_tx());
        t.outside_crossed(&frame, true);
        t.tick();
        assert!(t.take_tx_clock());
        assert_eq!(t.tx_data(), [0x20, 0, 0, 0, 12, 0, 0, 0, 0x01, 0x06, 0, 0]);
        // Confirmed once.
        t.take_to_bus();
        t.outside_crossed(&frame, true);
        assert!(!t.has_tx());
        t.sent(frame);
        t.outside_crossed(&frame, false);
        t.tick();
        assert_eq!(
            t.tx_data(),
            [0x31, 0, 0, 0, 15, 0, 0, 0, 0x01, 0x06, 0, 0, 0x05, 0x01, 0x01]
        );
    }

    /// `ARBITRATION_LOST_BEHAVIOR` (Configuration 0x40, Parameter 0x04): `DISCARD_AND_NOTIFY`
    /// (0x02) discards a frame that cannot go at once and answers Arbitration Lost (0x30,
    /// Total Length 12: OP Code, Length, ID; §4.4.1.2.4); `BUFFER_AND_RETRANSMIT` (0x01, and
    /// the default) sends none.
    #[test]
    fn discard_and_notify_answers_arbitration_lost_with_the_frames_id() {
        let mut t = CanTerminal::new(Some(125_000));
        assert!(!t.discards_on_arbitration_lost());
        let discard = [0x40, 0, 0, 0, 10, 0, 0, 0, 0x04, 0x02];
        let mut rx = discard.to_vec();
        rx.extend(transmit(0x601, &[1]));
        t.set_rx_data(&rx);
        t.set_rx_clock(true);
        t.update();
        assert!(t.discards_on_arbitration_lost());
        let [frame] = t.take_to_bus()[..] else {
            panic!("one frame")
        };
        t.arbitration_lost(&frame);
        t.tick();
        assert_eq!(t.tx_data(), [0x30, 0, 0, 0, 12, 0, 0, 0, 0x01, 0x06, 0, 0]);
        let buffer = [0x40, 0, 0, 0, 10, 0, 0, 0, 0x04, 0x01];
        t.set_rx_data(&buffer);
        t.set_rx_clock(true);
        t.update();
        assert!(!t.discards_on_arbitration_lost());
    }

    #[test]
    fn unreadable_operations_and_fd_frames_are_answered() {
        let mut t = CanTerminal::new(None);
        let junk = [0x77, 0, 0, 0, 8, 0, 0, 0];
        let mut rx = junk.to_vec();
        // A classic frame of nine bytes does not exist.
        rx.extend(transmit(0x601, &[0; 9]));
        Operation::CanFdTransmit {
            id: 5,
            ide: false,
            brs: true,
            esi: false,
            data: &[0; 12],
        }
        .emit(&mut rx)
        .unwrap();
        t.set_rx_data(&rx);
        t.set_rx_clock(true);
        t.update();
        assert!(t.take_tx_clock());
        let nine = transmit(0x601, &[0; 9]);
        let ops: Vec<_> = ls_bus::parse(t.tx_data()).map(Result::unwrap).collect();
        assert_eq!(
            ops,
            [
                Operation::FormatError { data: &junk },
                Operation::FormatError { data: &nine },
                Operation::BusError {
                    id: 5,
                    code: ErrorCode::FormError,
                    flag: ErrorFlag::Primary,
                    is_sender: true
                },
            ]
        );
        assert!(t.take_to_bus().is_empty());
    }

    #[test]
    fn the_terminals_file_names_every_member_of_every_bus() {
        let xml = terminals_and_icons(2);
        let doc = roxmltree::Document::parse(&xml).unwrap();
        let terminals: Vec<_> = doc
            .descendants()
            .filter(|n| n.has_tag_name("Terminal"))
            .collect();
        assert_eq!(terminals.len(), 2);
        for (b, t) in terminals.iter().enumerate() {
            assert_eq!(t.attribute("name"), Some(terminal_name(b).as_str()));
            assert_eq!(
                t.attribute("terminalKind"),
                Some("org.fmi-ls-bus.network-terminal")
            );
            let members: Vec<_> = t
                .children()
                .filter(|n| n.has_tag_name("TerminalMemberVariable"))
                .map(|n| n.attribute("memberName").unwrap())
                .collect();
            assert_eq!(members, ["Rx_Data", "Rx_Clock", "Tx_Data", "Tx_Clock"]);
        }
        roxmltree::Document::parse(MANIFEST).unwrap();
    }
}
