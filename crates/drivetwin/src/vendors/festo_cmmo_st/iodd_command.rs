//! `drivetwin iodd`: the IO-Link device descriptions of a personality, written as files.

use std::path::PathBuf;

use clap::Args;

use super::iodd::{file_name, write_iodd, Variant};
use crate::vendors::{device, CommandError};

// `drivetwin iodd`'s arguments (no doc comment: the sub-command's help is the variant's in
// the binary's command list).
#[derive(Args, Debug)]
pub struct IoddArgs {
    #[arg(long, default_value = "cmmo-st")]
    pub device: String,
    /// The folder to write them to.
    #[arg(long, default_value = ".")]
    pub output_dir: PathBuf,
    /// The files' date, YYYY-MM-DD (their names carry it as YYYYMMDD).
    #[arg(long, default_value = "2017-05-01")]
    pub date: String,
}

impl IoddArgs {
    /// Writes the files; the path of each goes to `out`.
    pub fn run(self, out: &mut dyn FnMut(&str)) -> Result<(), CommandError> {
        let IoddArgs {
            device: name,
            output_dir: dir,
            date,
        } = self;
        let desc = device(&name)?;
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
            write_iodd(desc, v, &date, &mut text)
                .map_err(|_| CommandError::Usage("IODD formatting failed".into()))?;
            let path = dir.join(file_name(v, &digits));
            std::fs::write(&path, text).map_err(|source| CommandError::Io {
                what: path.display().to_string(),
                source,
            })?;
            out(&path.display().to_string());
        }
        Ok(())
    }
}
