//! The stored parameter set of each node: one text file per node under the state directory,
//! replaced atomically (write a temporary file, fsync, rename, fsync the directory), so a kill
//! during a save leaves the old set or the new one, never a torn file.

use std::fs::{self, File};
use std::io::Write;
use std::path::{Path, PathBuf};

use od::parameter_file::{self, ParseError};
use od::ObjectDictionary;

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}:{line}: {error}")]
    Parse {
        path: PathBuf,
        line: usize,
        error: ParseError,
    },
}

/// Where one node's parameters live.
#[derive(Debug, Clone)]
pub struct ParamStore {
    path: PathBuf,
    /// The node-ID LSS "store configuration" saved (CiA 305), one number in a text file.
    lss_path: PathBuf,
    /// A device's own permanent memory as the device formats it (the CMMO-ST's EEPROM: its
    /// parameter file, App. C.4.3, checked by its CRC when it is loaded).
    memory_path: PathBuf,
}

/// One stored value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoredValue {
    pub index: u16,
    pub sub: u8,
    pub bytes: Vec<u8>,
}

impl ParamStore {
    /// The file of node `node` of personality `device` under `dir`.
    pub fn new(dir: &Path, device: &str, node: u8) -> Self {
        ParamStore {
            path: dir.join(format!("{device}-node{node}.params")),
            lss_path: dir.join(format!("{device}-node{node}.lss")),
            memory_path: dir.join(format!("{device}-node{node}.eeprom")),
        }
    }

    /// The node-ID stored by LSS, if any and valid.
    pub fn load_lss_node_id(&self) -> Option<u8> {
        let text = fs::read_to_string(&self.lss_path).ok()?;
        text.trim()
            .parse::<u8>()
            .ok()
            .filter(|id| (1..=127).contains(id))
    }

    pub fn save_lss_node_id(&self, node_id: u8) -> Result<(), StoreError> {
        write_atomically(&self.lss_path, format!("{node_id}\n").as_bytes())
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Where [`save_memory`](Self::save_memory) keeps the device's permanent memory.
    pub fn memory_path(&self) -> &Path {
        &self.memory_path
    }

    /// The device's permanent memory as last saved, `None` when nothing is stored.
    pub fn load_memory(&self) -> Result<Option<Vec<u8>>, StoreError> {
        match fs::read(&self.memory_path) {
            Ok(bytes) => Ok(Some(bytes)),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(source) => Err(StoreError::Io {
                path: self.memory_path.clone(),
                source,
            }),
        }
    }

    /// Replaces the stored permanent memory with `bytes` (atomically), or removes it (`None`:
    /// the device's memory was deleted, its factory settings come back at the next start).
    pub fn save_memory(&self, bytes: Option<&[u8]>) -> Result<(), StoreError> {
        match bytes {
            Some(bytes) => write_atomically(&self.memory_path, bytes),
            None => match fs::remove_file(&self.memory_path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(StoreError::Io {
                    path: self.memory_path.clone(),
                    source: e,
                }),
                _ => Ok(()),
            },
        }
    }

    /// The stored set, empty when nothing was ever saved.
    pub fn load(&self) -> Result<Vec<StoredValue>, StoreError> {
        let text = match fs::read_to_string(&self.path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
            Err(source) => {
                return Err(StoreError::Io {
                    path: self.path.clone(),
                    source,
                })
            }
        };
        let mut values = Vec::new();
        let mut buf = vec![0u8; 65536];
        for (i, line) in text.lines().enumerate() {
            match parameter_file::parse_line(line, &mut buf) {
                Ok(Some((index, sub, n))) => values.push(StoredValue {
                    index,
                    sub,
                    bytes: buf.get(..n).unwrap_or(&[]).to_vec(),
                }),
                Ok(None) => {}
                Err(error) => {
                    return Err(StoreError::Parse {
                        path: self.path.clone(),
                        line: i + 1,
                        error,
                    })
                }
            }
        }
        Ok(values)
    }

    /// Replaces the stored set with the dictionary's storable values (1010h:`sub`, merged
    /// with what is stored for the groups `sub` does not cover).
    pub fn save<S: AsRef<[u8]> + AsMut<[u8]>>(
        &self,
        od: &ObjectDictionary<S>,
        sub: u8,
    ) -> Result<(), StoreError> {
        self.write_text(&self.save_text(od, sub))
    }

    /// Replaces the stored set with `text` as [`save_text`](Self::save_text) made it (the
    /// slow part of a save, the file written and synced; it may run on a thread of its own).
    pub fn write_text(&self, text: &str) -> Result<(), StoreError> {
        write_atomically(&self.path, text.as_bytes())
    }

    /// The file [`save`](Self::save) writes: the dictionary's storable values now (1010h:`sub`,
    /// merged with what is stored for the groups `sub` does not cover).
    pub fn save_text<S: AsRef<[u8]> + AsMut<[u8]>>(
        &self,
        od: &ObjectDictionary<S>,
        sub: u8,
    ) -> String {
        let mut text =
            String::from("# drivetwin stored parameter set: IIII:SS=little-endian hex\n");
        let desc = od.description();
        let _ = std::fmt::Write::write_fmt(
            &mut text,
            format_args!("# device {} node {}\n", desc.name, od.node_id()),
        );
        let saved: Vec<(u16, u8)> = od
            .storable_values(sub)
            .map(|(e, _)| (e.index, e.sub))
            .collect();
        // Keep what this save does not cover (e.g. 1010h:02 saves only communication).
        for old in self.load().unwrap_or_default() {
            if !saved.contains(&(old.index, old.sub)) {
                if let Some(e) = desc.entry(old.index, old.sub) {
                    let _ = parameter_file::write_line(&mut text, e, &old.bytes);
                }
            }
        }
        for (e, bytes) in od.storable_values(sub) {
            let _ = parameter_file::write_line(&mut text, e, bytes);
        }
        text
    }
}

/// Replaces `path` so that a crash leaves the old or the new content, never a mix: write a
/// temporary file next to it, fsync, rename over, fsync the directory.
fn write_atomically(path: &Path, data: &[u8]) -> Result<(), StoreError> {
    let io = |source| StoreError::Io {
        path: path.to_path_buf(),
        source,
    };
    let dir = path.parent().unwrap_or(Path::new("."));
    fs::create_dir_all(dir).map_err(io)?;
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    {
        let mut f = File::create(&tmp).map_err(io)?;
        f.write_all(data).map_err(io)?;
        f.sync_all().map_err(io)?;
    }
    fs::rename(&tmp, path).map_err(io)?;
    // Make the rename itself durable.
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Puts stored values into the dictionary for the entries `filter` selects. Values for
/// entries the personality no longer has, or of the wrong size, are skipped with a warning.
pub fn apply<S: AsRef<[u8]> + AsMut<[u8]>>(
    od: &mut ObjectDictionary<S>,
    values: &[StoredValue],
    filter: impl Fn(u16) -> bool,
) {
    let desc = od.description();
    for v in values.iter().filter(|v| filter(v.index)) {
        match desc.entry(v.index, v.sub) {
            Some(e) if e.storable => {
                let fits = match e.data_type.fixed_size() {
                    Some(n) => v.bytes.len() == n,
                    None => v.bytes.len() <= e.capacity as usize,
                };
                if fits {
                    od.store(e, &v.bytes);
                } else {
                    tracing::warn!(
                        index = v.index,
                        sub = v.sub,
                        "stored value has the wrong size; default kept"
                    );
                }
            }
            _ => tracing::warn!(
                index = v.index,
                sub = v.sub,
                "stored value for an unknown or unstorable entry skipped"
            ),
        }
    }
}
