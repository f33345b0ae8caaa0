//! Parameter saves the runtime carries out for a front end that only asks for them: an
//! EtherCAT slave's 1010h "save" over CoE (`ecat::coe_dispatch`) holds its reply and hands
//! the runtime a [`SaveJob`], the dictionary's values as they were when the save was asked
//! for (what a save or restore asks for is decided in `cell::storage_request`). The file is
//! written by [`write()`], the atomic write a CANopen station's save uses (temporary file,
//! fsync, rename, fsync of the directory), so a kill during a save leaves the old set or the
//! new one. A [`ParamSaver`] writes it on a thread of its own: its
//! two fsyncs take tens of milliseconds on a loaded machine, longer than a master waits for
//! the frames the loop answers meanwhile.

use std::path::PathBuf;
use std::thread::JoinHandle;

use od::ObjectDictionary;

use super::param_store::{ParamStore, StoreError, StoredValue};

/// What a save gives back: the stored set as read back from the file written.
pub type SaveResult = Result<Vec<StoredValue>, StoreError>;

/// One save to carry out: the values to store, and where.
pub struct SaveJob {
    store: ParamStore,
    od: ObjectDictionary<Vec<u8>>,
    /// 1010h:`sub`, the parameter groups saved.
    sub: u8,
    /// Written on the loop, not beside it: the file has a writer on the loop already (the
    /// drive's CANopen node saves it from its SDO server), and one file has one writer.
    on_loop: bool,
}

impl SaveJob {
    /// The save of 1010h:`sub` of `od` (a copy of the dictionary as it is now) to `store`.
    pub fn new(store: ParamStore, od: ObjectDictionary<Vec<u8>>, sub: u8, on_loop: bool) -> Self {
        SaveJob {
            store,
            od,
            sub,
            on_loop,
        }
    }

    /// Writes the file (atomically) and reads the stored set back ([`write()`], as a CANopen
    /// station's save).
    pub fn run(self) -> SaveResult {
        write(&self.store, &self.od, self.sub)
    }

    /// Where the file goes.
    pub fn path(&self) -> &std::path::Path {
        self.store.path()
    }
}

/// The save of 1010h:`sub` of `od` to `store`, written now: the file replaced atomically, the
/// stored set read back from it.
pub fn write(store: &ParamStore, od: &ObjectDictionary<Vec<u8>>, sub: u8) -> SaveResult {
    store.save(od, sub)?;
    store.load()
}

/// The saves in progress of one runtime's front end, each known by the key `K` the front end
/// gives it (a slave's position on its chain).
pub struct ParamSaver<K> {
    running: Vec<(K, PathBuf, JoinHandle<SaveResult>)>,
    done: Vec<(K, SaveResult)>,
}

impl<K> Default for ParamSaver<K> {
    fn default() -> Self {
        ParamSaver {
            running: Vec::new(),
            done: Vec::new(),
        }
    }
}

impl<K> ParamSaver<K> {
    /// Starts `job` beside the loop (on the loop, when the job says so).
    pub fn start(&mut self, key: K, job: SaveJob) {
        if job.on_loop {
            let result = job.run();
            self.done.push((key, result));
            return;
        }
        let path = job.path().to_path_buf();
        let spawned = std::thread::Builder::new()
            .name("parameter-save".into())
            .spawn(move || job.run());
        match spawned {
            Ok(handle) => self.running.push((key, path, handle)),
            Err(source) => {
                tracing::error!(error = %source, "no thread to save the parameters");
                self.done.push((key, Err(StoreError::Io { path, source })));
            }
        }
    }

    /// A save that is done, with its result; `None` while every save started still writes.
    pub fn finished(&mut self) -> Option<(K, SaveResult)> {
        if let Some(done) = self.done.pop() {
            return Some(done);
        }
        let i = self.running.iter().position(|(_, _, h)| h.is_finished())?;
        let (key, path, handle) = self.running.swap_remove(i);
        let result = handle.join().unwrap_or_else(|_| {
            Err(StoreError::Io {
                path,
                source: std::io::Error::other("the writer thread panicked"),
            })
        });
        Some((key, result))
    }
}
