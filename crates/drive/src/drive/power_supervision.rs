//! The supply and the motor's load as the drive supervises them: the DC link voltage
//! (6079h dc_link_circuit_voltage; a vendor's undervoltage threshold,
//! the vendor hook `dc_link_undervoltage_mv`) and I²t, an error where the vendor makes it one
//! (the vendor hook `i2t_is_error`). CiA 402 names neither supervision: at the hooks' defaults the
//! drive shows the voltage and limits the current, and reports nothing.

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// The supply: the DC-link voltage in mV (`None`: the nominal one). It shows in 6079h
    /// (and where the vendor has one, its own object, `Vendor`'s `POWER_STAGE_OBJECTS`), limits the current
    /// controller's output voltage, and below the vendor's threshold it is the vendor's
    /// undervoltage error (the vendor hook `dc_link_undervoltage_mv`).
    pub fn set_dc_link_voltage(&mut self, mv: Option<u32>) {
        self.dc_link_mv = mv;
        publish_supply::<S, V>(&mut self.od, mv);
        self.params_dirty = true;
    }

    /// DC-link undervoltage below the vendor's threshold; the cause stays while the voltage
    /// is low.
    pub(super) fn supervise_dc_link(&mut self) {
        let min = V::dc_link_undervoltage_mv(self);
        let low = self
            .dc_link_mv
            .filter(|mv| min.is_some_and(|min| i64::from(*mv) < min));
        // Nothing to raise and no cause to end (every cycle of a healthy supply): the error's
        // lookup is a search of the personality's table.
        if low.is_none() && self.causes.is_empty() {
            return;
        }
        let Some(e) = self.personality.error(Fault::DcLinkUndervoltage) else {
            return;
        };
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

    /// The motor I²t at 100 % as the vendor's error, where it makes it one; the cause stays
    /// until the I²t has fallen below the release threshold.
    pub(super) fn supervise_i2t(&mut self) {
        let over = V::i2t_is_error(self) && self.axis.i2t_limit_active();
        // As `cause` has it: not over and no cause present changes nothing.
        if !over && self.causes.is_empty() {
            return;
        }
        if let Some(e) = self.personality.error(Fault::I2tMotor) {
            self.cause(e.code, over, e.register);
        }
    }
}
