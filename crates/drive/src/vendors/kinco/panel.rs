//! The Kinco CD3 / FD3 LED panel (Kinco CD3 / FD3 manual ch. 4, ch. 9): five 7-segment digits with
//! their points and the keys MODE / SET / ▲ / ▼, as a state machine on the drive. Key presses come
//! in with the drive's clock (the time of its last step); the display is read as five characters
//! and points.
//!
//! The parameter groups are data: the panel addresses of the device file (`panel = "d3.01"`,
//! generated into `devices::*_ADDRESSES`), so every address the manual gives is reachable and
//! nothing is listed twice. Edits go through the drive's normal object write
//! ([`ObjectAccess::write`]), with the same rules and side effects as over CANopen or RS232.
//!
//! Digits are numbered 1…5 from the left, point n follows digit n (§4.1): a four-character
//! text sits in digits 2…5, so "d3.01" lights point 3 and the alarm code "020.0" point 4.

use od::{AbortCode, Instant, ObjectAccess};

use super::hooks::Kinco;
use super::ErrorWord;
use crate::device_control::State;
use crate::drive::Drive;

/// A key of the panel (§4.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PanelKey {
    Mode,
    Set,
    Up,
    Down,
}

impl PanelKey {
    const fn slot(self) -> usize {
        match self {
            PanelKey::Mode => 0,
            PanelKey::Set => 1,
            PanelKey::Up => 2,
            PanelKey::Down => 3,
        }
    }
}

/// How the whole display blinks (§4.1): once a second on an error, three quick blinks
/// repeating on a warning.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Blink {
    #[default]
    Steady,
    Error,
    Warning,
}

/// What the five digits show.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PanelDisplay {
    /// Digits 1…5 from the left, ASCII (`b' '` dark).
    pub chars: [u8; 5],
    /// Points: bit n−1 = point n lit.
    pub dots: u8,
    pub blink: Blink,
    /// Point 5 blinks: the power stage is enabled (§4.1).
    pub dot5_blinks: bool,
    /// The digit (1…5) being edited, which blinks on the drive.
    pub cursor: Option<u8>,
}

impl PanelDisplay {
    fn text4(s: &[u8], dots: u8) -> PanelDisplay {
        let mut chars = *b"     ";
        for (c, b) in chars.iter_mut().skip(1).zip(s) {
            *c = *b;
        }
        PanelDisplay {
            chars,
            dots,
            blink: Blink::Steady,
            dot5_blinks: false,
            cursor: None,
        }
    }

    /// The digits with their points as text: `" d3.01"`, `" 020.0"`.
    pub fn text(&self) -> heapless::String<10> {
        let mut s = heapless::String::new();
        for (i, c) in self.chars.iter().enumerate() {
            let _ = s.push(char::from(*c));
            if self.dots & (1 << i) != 0 {
                let _ = s.push('.');
            }
        }
        s
    }
}

/// Point 3 (§4.1): group separator, high half of a 32-bit value, earliest F007 entry.
pub const DOT3: u8 = 1 << 2;
/// Point 4: HEX, latest F007 entry.
pub const DOT4: u8 = 1 << 3;
/// Point 5: a parameter was changed successfully.
pub const DOT5: u8 = 1 << 4;

/// The function menus MODE steps through (§4.2, ch. 9), with the panel-address prefix of
/// their parameters. F006 and F007 have none (jog, history).
const MENUS: [(&[u8; 4], &str); 9] = [
    (b"F001", "d1."),
    (b"F002", "d2."),
    (b"F003", "d3."),
    (b"F004", "d4."),
    (b"F005", "d5."),
    (b"F006", ""),
    (b"F007", ""),
    (b"EASY", "EA"),
    (b"tunE", "tn"),
];
const F001: u8 = 0;
const F006: u8 = 5;
const F007: u8 = 6;
const EASY: u8 = 7;
const TUNE: u8 = 8;

/// Decision: the manual does not say how long a long press is; 1 s.
pub const LONG_PRESS_NS: u64 = 1_000_000_000;
/// §4.3.1 note: EASY (and tunE, same procedure) close after 30 s without a key.
pub const MENU_TIMEOUT_NS: u64 = 30_000_000_000;
/// §4.3.3: jog ends after 20 s without a key.
pub const JOG_TIMEOUT_NS: u64 = 20_000_000_000;

/// The EASY / tunE items allowed while the access lock holds (§4.3).
const UNLOCKED: [&str; 3] = ["EA00", "EA01", "tn00"];
/// The "save" items whose value 10 initialises the parameters (§4.3.1 EA00, tn00, d2.00).
const INIT_VALUE: i64 = 10;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
enum Screen {
    #[default]
    Monitor,
    Menu(u8),
    Browse {
        menu: u8,
        item: u8,
    },
    Edit {
        menu: u8,
        item: u8,
        value: i64,
        cursor: u8,
        high: bool,
    },
    JogCheck {
        shown: u8,
        reached_15: bool,
    },
    Jog {
        direction: i8,
    },
    History {
        item: u8,
        second: bool,
    },
}

/// The panel's state.
#[derive(Debug, Clone, Default)]
pub struct Panel {
    screen: Screen,
    /// When each key went down (MODE, SET, ▲, ▼).
    held: [Option<Instant>; 4],
    last_key: Option<Instant>,
    /// Point 5 after a successful change, until the next key.
    changed: bool,
    /// The motor type (6410h:01) confirmed in EA01 (at first power-on: the one found).
    confirmed_motor: Option<i64>,
    /// The parameters were initialised from the panel (value 10): lock until EA01.
    initialised: bool,
    /// The panel enabled the drive for jog.
    jog_enabled: bool,
    /// Monitor: SET on an extended error shows Error_State2 (ch. 8, KINCO-DIAG-06).
    monitor_second: bool,
    /// Monitor: a long SET shows the high half of a 32-bit value (§4.1).
    monitor_high: bool,
}

/// A value in the panel's formats: DEC in five digits where it fits (a '-' in front), else
/// the 16-bit half in four HEX digits with point 4 (point 3 for the high half).
///
/// Decision: §4.1 says point 4 marks HEX and point 3 the high half of 32-bit data, and that
/// EA03/EA04 switch to HEX above 9999 ([`format_value_of`]); it does not say where other
/// values switch. Here: DEC for −9999…99999, HEX outside.
fn format_value(v: i64, high: bool) -> (PanelDisplay, bool) {
    format_value_up_to(v, high, 99999)
}

/// [`format_value`] for the item `key`: EA03 / EA04 (the gear, Tab. 4-2 L583-584) "in DEC;
/// above 9999 in HEX".
fn format_value_of(key: Option<&str>, v: i64, high: bool) -> (PanelDisplay, bool) {
    match key {
        Some("EA03" | "EA04") => format_value_up_to(v, high, 9999),
        _ => format_value(v, high),
    }
}

fn format_value_up_to(v: i64, high: bool, dec_max: i64) -> (PanelDisplay, bool) {
    if (-9999..=dec_max).contains(&v) {
        let mut chars = *b"     ";
        let mut n = v.unsigned_abs();
        for c in chars.iter_mut().rev() {
            *c = b'0' + (n % 10) as u8;
            n /= 10;
            if n == 0 {
                break;
            }
        }
        if v < 0 {
            chars[0] = b'-';
        }
        let d = PanelDisplay {
            chars,
            ..PanelDisplay::text4(b"", 0)
        };
        (d, false)
    } else {
        let half = if high { (v >> 16) & 0xFFFF } else { v & 0xFFFF };
        let dots = DOT4 | if high { DOT3 } else { 0 };
        (PanelDisplay::text4(&hex4(half as u16), dots), true)
    }
}

fn hex4(v: u16) -> [u8; 4] {
    const HEX: &[u8; 16] = b"0123456789ABCDEF";
    let d = |s: u16| {
        HEX.get(usize::from((v >> s) & 0xF))
            .copied()
            .unwrap_or(b'0')
    };
    [d(12), d(8), d(4), d(0)]
}

/// A panel address ("d3.01", "EA02") as the display's four characters and point 3.
fn address_display(key: &str) -> PanelDisplay {
    let b = key.as_bytes();
    if let [g, n, b'.', x, y] = b {
        PanelDisplay::text4(&[*g, *n, *x, *y], DOT3)
    } else {
        PanelDisplay::text4(b, 0)
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, Kinco> {
    fn panel_addresses(&self) -> &'static devices::Addresses {
        devices::addresses(self.od.description().name).unwrap_or(&devices::KINCO_FD3_ADDRESSES)
    }

    /// The access lock of §4.3: the parameters were initialised, or the motor type
    /// (6410h:01) is not the one confirmed in EA01.
    pub fn kinco_panel_locked(&self) -> bool {
        self.vendor.panel.initialised || self.kinco_motor_mismatch()
    }

    fn kinco_motor_mismatch(&self) -> bool {
        self.vendor
            .panel
            .confirmed_motor
            .is_some_and(|m| m != self.value(0x6410, 0x01))
    }

    /// The panel addresses of menu `menu` in the order the panel shows them: sorted, the
    /// "save" item x00 of EASY and tunE last (§4.2), only EA00 / EA01 / tn00 while locked.
    fn panel_item(&self, menu: u8, item: u8) -> Option<&'static str> {
        self.panel_items(menu).nth(usize::from(item))
    }

    fn panel_items(&self, menu: u8) -> impl Iterator<Item = &'static str> + '_ {
        let prefix = MENUS.get(usize::from(menu)).map(|m| m.1).unwrap_or("");
        let special = menu == EASY || menu == TUNE;
        let locked = special && self.kinco_panel_locked();
        let all = self.panel_addresses().panel.iter().map(|p| p.key);
        let keys = move || {
            all.clone()
                .filter(move |k| !prefix.is_empty() && k.starts_with(prefix))
                .filter(move |k| !locked || UNLOCKED.contains(k))
        };
        let last = move |k: &&str| special && k.ends_with("00");
        // EA00 / tn00 (§4.3.1 "save"): no object of their own in the manual; the panel's
        // own item where the device file gives none (see `panel_save`).
        let save = match menu {
            EASY => Some("EA00"),
            TUNE => Some("tn00"),
            _ => None,
        }
        .filter(|k| self.panel_addresses().panel(k).is_none());
        keys()
            .filter(move |k| !last(k))
            .chain(keys().filter(move |k| last(k)))
            .chain(save)
    }

    fn panel_count(&self, menu: u8) -> u8 {
        self.panel_items(menu).count().min(255) as u8
    }

    /// A key of the panel went down (`pressed`) or up, at the drive's clock.
    pub fn kinco_panel_key(&mut self, key: PanelKey, pressed: bool) {
        let now = self.now;
        self.kinco_panel_timeouts(now);
        let slot = key.slot();
        let down_at = self.vendor.panel.held.get(slot).copied().flatten();
        if let Some(h) = self.vendor.panel.held.get_mut(slot) {
            *h = if pressed { down_at.or(Some(now)) } else { None };
        }
        self.vendor.panel.last_key = Some(now);
        match (key, pressed) {
            // ▲ / ▼ act when they go down; jog runs while they are held.
            (PanelKey::Up | PanelKey::Down, true) if down_at.is_none() => {
                self.vendor.panel.changed = false;
                self.panel_step(if key == PanelKey::Up { 1 } else { -1 });
            }
            (PanelKey::Up | PanelKey::Down, false) => {
                if let Screen::Jog { .. } = self.vendor.panel.screen {
                    self.vendor.panel.screen = Screen::Jog { direction: 0 };
                }
            }
            // MODE and SET act when they come up: short or long.
            (PanelKey::Mode | PanelKey::Set, false) => {
                let Some(at) = down_at else { return };
                let long = now.saturating_since(at).as_nanos() >= u128::from(LONG_PRESS_NS);
                if key == PanelKey::Mode {
                    self.panel_mode(long);
                } else {
                    self.panel_set(long);
                }
            }
            _ => {}
        }
    }

    fn panel_step(&mut self, d: i8) {
        let screen = self.vendor.panel.screen;
        match screen {
            Screen::Menu(_) | Screen::Monitor => {}
            Screen::Browse { menu, item } => {
                let n = self.panel_count(menu);
                if n > 0 {
                    let item = if d > 0 {
                        (item + 1) % n
                    } else {
                        (item + n - 1) % n
                    };
                    self.vendor.panel.screen = Screen::Browse { menu, item };
                }
            }
            Screen::Edit {
                menu,
                item,
                value,
                cursor,
                high,
            } => {
                let hex = format_value_of(self.panel_item(menu, item), value, high).1;
                let step: i64 = if hex {
                    16i64.pow(u32::from(cursor)) << if high { 16 } else { 0 }
                } else {
                    10i64.pow(u32::from(cursor))
                };
                let value = value.saturating_add(i64::from(d) * step);
                self.vendor.panel.screen = Screen::Edit {
                    menu,
                    item,
                    value,
                    cursor,
                    high,
                };
            }
            // §4.3.3 step 3: ▼ down to d6.15, then ▲ up to d6.25 (the keys' health check).
            Screen::JogCheck { shown, reached_15 } => {
                let shown = if d > 0 {
                    shown.saturating_add(1).min(99)
                } else {
                    shown.saturating_sub(1)
                };
                self.vendor.panel.screen = Screen::JogCheck {
                    shown,
                    reached_15: reached_15 || shown == 15,
                };
            }
            Screen::Jog { .. } => self.vendor.panel.screen = Screen::Jog { direction: d },
            Screen::History { item, .. } => {
                let n = self.vendor.history.len().min(255) as u8;
                if n > 0 {
                    let item = if d > 0 {
                        (item + 1) % n
                    } else {
                        (item + n - 1) % n
                    };
                    self.vendor.panel.screen = Screen::History {
                        item,
                        second: false,
                    };
                }
            }
        }
    }

    /// MODE (§4.1): steps through the function menus; while editing a short press moves to
    /// the next digit and a long press goes back to the last menu.
    ///
    /// Decision: after tunE MODE returns to the monitor display; in a parameter list or a
    /// special screen MODE (short or long) goes back to its menu.
    fn panel_mode(&mut self, long: bool) {
        self.vendor.panel.changed = false;
        let p = &mut self.vendor.panel;
        p.monitor_second = false;
        p.monitor_high = false;
        let screen = p.screen;
        self.vendor.panel.screen = match screen {
            Screen::Monitor => Screen::Menu(0),
            Screen::Menu(m) if usize::from(m) + 1 < MENUS.len() => Screen::Menu(m + 1),
            Screen::Menu(_) => Screen::Monitor,
            Screen::Edit {
                menu,
                item,
                value,
                cursor,
                high,
            } if !long => {
                let key = self.panel_item(menu, item);
                let digits = if format_value_of(key, value, high).1 {
                    4
                } else {
                    5
                };
                Screen::Edit {
                    menu,
                    item,
                    value,
                    cursor: (cursor + 1) % digits,
                    high,
                }
            }
            Screen::Edit { menu, item, .. } => Screen::Browse { menu, item },
            Screen::Browse { menu, .. } => Screen::Menu(menu),
            Screen::JogCheck { .. } | Screen::Jog { .. } => Screen::Menu(F006),
            Screen::History { .. } => Screen::Menu(F007),
        };
    }

    /// SET (§4.1): enter a menu, show a value, confirm and go on. A long press on a HEX
    /// (32-bit) value toggles its high / low half.
    fn panel_set(&mut self, long: bool) {
        self.vendor.panel.changed = false;
        match self.vendor.panel.screen {
            Screen::Monitor => {
                let p = &mut self.vendor.panel;
                if long {
                    p.monitor_high = !p.monitor_high;
                } else {
                    p.monitor_second = !p.monitor_second;
                }
            }
            Screen::Menu(F006) => {
                self.vendor.panel.screen = Screen::JogCheck {
                    shown: 40,
                    reached_15: false,
                }
            }
            Screen::Menu(F007) => {
                let n = self.vendor.history.len().min(255) as u8;
                self.vendor.panel.screen = Screen::History {
                    item: n.saturating_sub(1),
                    second: false,
                }
            }
            Screen::Menu(menu) => self.vendor.panel.screen = Screen::Browse { menu, item: 0 },
            Screen::Browse { menu, item } => {
                let Some(key) = self.panel_item(menu, item) else {
                    return;
                };
                if menu == F001 {
                    // §9.1: SET chooses the monitor item; Key_Address_F001 2FF0h:04 = n.
                    let n = key
                        .get(3..)
                        .and_then(|s| s.parse::<u8>().ok())
                        .unwrap_or(25);
                    if self.write(0x2FF0, 0x04, &[n]).is_ok() {
                        self.vendor.panel.screen = Screen::Monitor;
                    }
                    return;
                }
                // The save items read 0 (§4.3.1 EA00 "/" default).
                let value = self
                    .panel_addresses()
                    .panel(key)
                    .map_or(0, |(index, sub)| self.value(index, sub));
                self.vendor.panel.screen = Screen::Edit {
                    menu,
                    item,
                    value,
                    cursor: 0,
                    high: false,
                };
            }
            Screen::Edit {
                menu,
                item,
                value,
                cursor,
                high,
            } => {
                if long {
                    if format_value_of(self.panel_item(menu, item), value, high).1 {
                        self.vendor.panel.screen = Screen::Edit {
                            menu,
                            item,
                            value,
                            cursor,
                            high: !high,
                        };
                    }
                    return;
                }
                let Some(key) = self.panel_item(menu, item) else {
                    return;
                };
                if self.panel_write(key, value).is_ok() {
                    self.vendor.panel.changed = true;
                }
                self.vendor.panel.screen = Screen::Browse { menu, item };
            }
            Screen::JogCheck { shown, reached_15 } => {
                if reached_15 && shown == 25 {
                    self.vendor.panel.screen = Screen::Jog { direction: 0 };
                }
            }
            Screen::Jog { .. } => {}
            Screen::History { item, second } => {
                // F007: an extended error (0001) shows Error_State2 on SET.
                let ext = self
                    .history_word(item)
                    .is_some_and(|(w, _)| w == ErrorWord::State2);
                if ext {
                    self.vendor.panel.screen = Screen::History {
                        item,
                        second: !second,
                    };
                }
            }
        }
    }

    /// Writes the value of panel address `key` through the drive's object write (the rules
    /// and side effects of a CANopen or RS232 write); EA01 confirms the motor type, value 10
    /// in a save item initialises the parameters and locks EASY / tunE (§4.3).
    fn panel_write(&mut self, key: &str, value: i64) -> Result<(), AbortCode> {
        if (key == "EA00" || key == "tn00") && self.panel_addresses().panel(key).is_none() {
            return self.panel_save(value);
        }
        let (index, sub) = self
            .panel_addresses()
            .panel(key)
            .ok_or(AbortCode::NO_OBJECT)?;
        let entry = self.od.entry(index, sub)?;
        let len = (entry.capacity as usize).clamp(1, 8);
        let bytes = value.to_le_bytes();
        let data = bytes.get(..len).ok_or(AbortCode::LENGTH_MISMATCH)?;
        if key.starts_with("tn") {
            // §5.9: over communication WriteFUN_CTL 3041h:05 = 1 opens the tuning objects
            // (Tuning_Method, Stiffness); the panel's tunE writes them directly. Decision:
            // the panel opens it for its write and restores it after.
            let before = self.value(0x3041, 0x05);
            self.write(0x3041, 0x05, &[1])?;
            let done = self.write(index, sub, data);
            let _ = self.write(0x3041, 0x05, &[before.clamp(0, 255) as u8]);
            done?;
        } else {
            self.write(index, sub, data)?;
        }
        if key == "EA01" {
            self.vendor.panel.confirmed_motor = Some(self.value(0x6410, 0x01));
            self.vendor.panel.initialised = false;
        } else if ((index, sub) == (0x2FF0, 0x01) || key == "EA00" || key == "tn00")
            && value == INIT_VALUE
        {
            self.vendor.panel.initialised = true;
        }
        Ok(())
    }

    /// EA00 / tn00 (§4.3.1): 1 saves the control and the motor parameters (the loop set by
    /// EA06's load type first, then Store_Data 2FF0h:01 := 1, Store_Motor_Data 2FF0h:03 :=
    /// 1), 2 saves and reboots, 3 reboots (`kinco_easy.rs`), 10 initialises the control
    /// parameters (2FF0h:01 := 10) and locks EASY / tunE (§4.3). Other values are refused.
    fn panel_save(&mut self, value: i64) -> Result<(), AbortCode> {
        match value {
            1 => self.kinco_easy_save(),
            2 => {
                self.kinco_easy_save()?;
                self.kinco_reboot();
                Ok(())
            }
            3 => {
                self.kinco_reboot();
                Ok(())
            }
            INIT_VALUE => {
                self.write(0x2FF0, 0x01, &[INIT_VALUE as u8])?;
                self.vendor.panel.initialised = true;
                Ok(())
            }
            _ => Err(AbortCode::INVALID_VALUE),
        }
    }

    /// The Error_State word and bit of history entry `item` (oldest first).
    fn history_word(&self, item: u8) -> Option<(ErrorWord, u8)> {
        let code = self.vendor.history.iter().nth(usize::from(item))?;
        self.kinco_error_bit(*code)
    }

    /// The confirmed motor type at first power-on: the motor found (§4.3.1 EA01: a new drive
    /// on a motor recognises and stores it).
    pub(crate) fn kinco_panel_power_on(&mut self) {
        if self.vendor.panel.confirmed_motor.is_none() {
            self.vendor.panel.confirmed_motor = Some(self.value(0x6410, 0x01));
        }
    }

    fn kinco_panel_timeouts(&mut self, now: Instant) {
        let idle = self
            .vendor
            .panel
            .last_key
            .map(|t| now.saturating_since(t).as_nanos())
            .unwrap_or(0);
        let any_held = self.vendor.panel.held.iter().any(Option::is_some);
        let limit = match self.vendor.panel.screen {
            Screen::JogCheck { .. } | Screen::Jog { .. } => JOG_TIMEOUT_NS,
            Screen::Browse { menu, .. } | Screen::Edit { menu, .. }
                if menu == EASY || menu == TUNE =>
            {
                MENU_TIMEOUT_NS
            }
            _ => return,
        };
        if !any_held && idle >= u128::from(limit) {
            self.vendor.panel.screen = Screen::Monitor;
        }
    }

    /// Once a logic cycle: the timeouts, and jog (§4.3.3): while ▲ / ▼ is held the panel
    /// enables the drive (6040h 06h, then 0Fh: Tab. 6-5) and turns at Jog_RPM in mode −3;
    /// on release it stops and disables again.
    ///
    /// Decision: jog runs "independent of other settings" (§4.3.3), so the panel sets the
    /// controlword as a DIN function does (a local source, not refused where the Enable DIN
    /// owns 6040h, L1287); a Pre_Enable DIN still has to be active (External enable).
    pub(crate) fn kinco_panel_cycle(&mut self) {
        self.kinco_panel_timeouts(self.now);
        let direction = match self.vendor.panel.screen {
            Screen::Jog { direction } => direction,
            _ => 0,
        };
        if direction != 0 {
            let cw: Option<u8> = match self.state() {
                State::SwitchOnDisabled => Some(0x06),
                State::ReadyToSwitchOn | State::SwitchedOn => Some(0x0F),
                _ => None,
            };
            if let Some(cw) = cw {
                self.kinco_set_controlword(u16::from(cw));
            }
            self.vendor.panel.jog_enabled = true;
            if self.state() == State::OperationEnabled {
                self.jog(direction);
            }
        } else if self.vendor.panel.jog_enabled {
            self.vendor.panel.jog_enabled = false;
            self.jog(0);
            self.kinco_set_controlword(0x06);
        }
    }

    /// What the panel shows now.
    pub fn kinco_panel(&self) -> PanelDisplay {
        let p = &self.vendor.panel;
        let mut d = match p.screen {
            Screen::Monitor => return self.panel_monitor(),
            Screen::Menu(m) => {
                PanelDisplay::text4(MENUS.get(usize::from(m)).map_or(b"    ", |m| m.0), 0)
            }
            Screen::Browse { menu, item } => self
                .panel_item(menu, item)
                .map_or(PanelDisplay::text4(b"----", 0), address_display),
            Screen::Edit {
                menu,
                item,
                value,
                cursor,
                high,
            } => {
                let mut d = format_value_of(self.panel_item(menu, item), value, high).0;
                d.cursor = Some(5 - cursor);
                d
            }
            Screen::JogCheck { shown, .. } => {
                PanelDisplay::text4(&[b'd', b'6', b'0' + shown / 10, b'0' + shown % 10], DOT3)
            }
            Screen::Jog { .. } => PanelDisplay::text4(b"Jog ", 0),
            Screen::History { item, second } => self.panel_history(item, second),
        };
        if p.changed {
            d.dots |= DOT5;
        }
        d.dot5_blinks = self.state() == State::OperationEnabled;
        d
    }

    /// F007 (§4.3.4, Tab. 4-6): the entry's Error_State value in HEX, point 3 on the earliest
    /// and point 4 on the latest entry. Decision: an empty history shows "----".
    fn panel_history(&self, item: u8, second: bool) -> PanelDisplay {
        let n = self.vendor.history.len();
        let Some((word, bit)) = self.history_word(item) else {
            return PanelDisplay::text4(b"----", 0);
        };
        let v: u16 = match (word, second) {
            (ErrorWord::State2, false) => 1,
            _ => 1u16.checked_shl(u32::from(bit)).unwrap_or(0),
        };
        let mut dots = 0;
        if item == 0 {
            dots |= DOT3;
        }
        if usize::from(item) + 1 == n {
            dots |= DOT4;
        }
        PanelDisplay::text4(&hex4(v), dots)
    }

    /// The monitor display (§4, §9.1): a blinking "FFF.F" on a motor-type mismatch, the
    /// blinking alarm code of an error (ch. 8), else d1.n of Key_Address_F001 2FF0h:04
    /// (default d1.25 Real_Speed_RPM), with the warning blink while Warning_Word is not 0.
    fn panel_monitor(&self) -> PanelDisplay {
        let mut d = if self.kinco_motor_mismatch() {
            PanelDisplay {
                blink: Blink::Error,
                ..PanelDisplay::text4(b"FFFF", DOT4)
            }
        } else if let Some(code) = self.kinco_led().map(|code| {
            // ch. 8: "000.1" is the extended error; SET shows Error_State2 (d1.16).
            let state2 = self.value(0x2602, 0) as u16;
            if self.vendor.panel.monitor_second && &code == b"000.1" && state2 != 0 {
                super::led_code(state2.trailing_zeros() as u8)
            } else {
                code
            }
        }) {
            let digits: heapless::Vec<u8, 5> =
                code.iter().copied().filter(|c| *c != b'.').collect();
            let dot = code.iter().position(|c| *c == b'.').unwrap_or(3);
            PanelDisplay {
                blink: Blink::Error,
                // The point follows the digit before it; text4 shifts by one digit.
                ..PanelDisplay::text4(&digits, 1 << dot)
            }
        } else {
            let n = self.value(0x2FF0, 0x04);
            let mut key: heapless::String<5> = heapless::String::new();
            let _ = core::fmt::write(&mut key, format_args!("d1.{n:02}"));
            let (index, sub) = self.panel_addresses().panel(&key).unwrap_or((0x2FF0, 0x14));
            let mut d = format_value(self.value(index, sub), self.vendor.panel.monitor_high).0;
            if self.vendor.warnings != 0 {
                d.blink = Blink::Warning;
            }
            d
        };
        d.dot5_blinks = self.state() == State::OperationEnabled;
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// §4.1: DEC in five digits; beyond, the 16-bit halves in HEX with point 4, point 3 on the
    /// high half (123 456 = 0001_E240h).
    #[test]
    fn value_formats() {
        assert_eq!(format_value(30, false).0.text().as_str(), "   30");
        assert_eq!(format_value(-250, false).0.text().as_str(), "- 250");
        let (low, hex) = format_value(123_456, false);
        assert!(hex);
        assert_eq!(low.text().as_str(), " E24.0");
        assert_eq!(format_value(123_456, true).0.text().as_str(), " 00.0.1");
    }

    /// §4.1 point 3 separates group and address; Tab. 4-6 "02.00" style for the history.
    #[test]
    fn address_and_hex_layout() {
        assert_eq!(address_display("d3.01").text().as_str(), " d3.01");
        assert_eq!(address_display("EA02").text().as_str(), " EA02");
        assert_eq!(
            PanelDisplay::text4(&hex4(0x0200), DOT3).text().as_str(),
            " 02.00"
        );
    }
}
