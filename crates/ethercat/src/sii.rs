//! SII EEPROM image (in progress).
