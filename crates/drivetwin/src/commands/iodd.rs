//! `drivetwin iodd`: the IO-Link device descriptions of a personality, written as files.

use std::path::Path;

use drivetwin::export::iodd::{file_name, write_iodd, Variant};

use super::{device, io, CommandError};

pub(crate) fn iodd(name: &str, dir: &Path, date: &str) -> Result<(), CommandError> {
    let desc = device(name)?;
    if desc.name != "cmmo-st" {
        return Err(CommandError::Usage(format!(
            "{name} has no IO-Link interface (only the CMMO-ST's manual names IODD files)"
        )));
    }
    let digits: String = date.chars().filter(char::is_ascii_digit).collect();
    let valid = date.len() == 10
        && digits.len() == 8
        && date.as_bytes().get(4) == Some(&b'-')
        && date.as_bytes().get(7) == Some(&b'-');
    if !valid {
        return Err(CommandError::Usage(format!("--date {date:?}: YYYY-MM-DD")));
    }
    for v in Variant::ALL {
        let mut text = String::new();
        write_iodd(desc, v, date, &mut text)
            .map_err(|_| CommandError::Usage("IODD formatting failed".into()))?;
        let path = dir.join(file_name(v, &digits));
        std::fs::write(&path, text).map_err(io(path.display().to_string()))?;
        out!("{}", path.display());
    }
    Ok(())
}
