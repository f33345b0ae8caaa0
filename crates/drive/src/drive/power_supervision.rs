//! The supply and the motor's load as the drive supervises them: the DC link voltage
//! (6510h:34, 6079h, undervoltage) and I²t.

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// The supply: the DC-link voltage in mV (`None`: the nominal 6510h:33). It shows in
    /// 6510h:34 and 6079h, limits the current controller's output voltage, and below
    /// 6510h:36 with 6510h:37 = 1 it is error 02-0.
    pub fn set_dc_link_voltage(&mut self, mv: Option<u32>) {
        self.dc_link_mv = mv;
        publish_supply(&mut self.od, mv, V::MANUFACTURER_OBJECTS);
        self.params_dirty = true;
    }

    /// CMMP-AS 02-0 DC-link undervoltage (6510h:36 min_dc_link_circuit_voltage, 6510h:37
    /// enable_dc_link_undervoltage_error); the cause stays while the voltage is low.
    pub(super) fn supervise_dc_link(&mut self) {
        let Some(e) = self.personality.error(Fault::DcLinkUndervoltage) else {
            return;
        };
        let enabled = self.value(0x6510, 0x37) == 1;
        let min = self.value(0x6510, 0x36);
        let low = self.dc_link_mv.filter(|mv| enabled && i64::from(*mv) < min);
        if low.is_some() {
            if !self.causes.contains(&e.code) {
                let _ = self.causes.push(e.code);
            }
            self.raise_detected(
                e.code,
                e.register,
                e.critical,
                Some(Fault::DcLinkUndervoltage),
            );
        } else if let Some(i) = self.causes.iter().position(|c| *c == e.code) {
            if !self.injected_code(e.code) {
                self.causes.remove(i);
            }
        }
    }

    /// CMMP-AS 31-0 I²t motor (§5.5, 6510h:38 iit_error_enable = 1): the motor I²t at 100 %
    /// is an error, not only the limitation to the rated current; the cause stays until the
    /// I²t has fallen below the release threshold.
    pub(super) fn supervise_i2t(&mut self) {
        let over = self.value(0x6510, 0x38) == 1 && self.axis.i2t_limit_active();
        if let Some(e) = self.personality.error(Fault::I2tMotor) {
            self.cause(e.code, over, e.register);
        }
    }
}
