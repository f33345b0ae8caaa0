//! The stations of a cell in one list. A station ([`Station`]) is one drive with all its front
//! ends; the buses between them name the stations by [`StationId`] instead of owning them, so
//! a drive that is a CANopen node and an EtherCAT slave at once is one entry here, reached by
//! both. The list only grows while a cell is built; an id stays valid for the life of the cell.

use std::ops::{Deref, DerefMut};

use super::station::Station;

/// A station's place in its cell's [`Stations`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct StationId(u32);

impl StationId {
    /// The id of the station at `index` in its list.
    pub const fn from_index(index: usize) -> Self {
        if index > u32::MAX as usize {
            StationId(u32::MAX)
        } else {
            StationId(index as u32)
        }
    }

    /// Its place in the list.
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// The stations of a cell, in the order they were added; read as a slice in that order.
#[derive(Default)]
pub struct Stations {
    list: Vec<Station>,
}

impl Stations {
    pub fn new() -> Self {
        Stations::default()
    }

    /// Adds `station` to the cell; its id.
    pub fn push(&mut self, station: Station) -> StationId {
        let id = StationId::from_index(self.list.len());
        self.list.push(station);
        id
    }

    pub fn station(&self, id: StationId) -> Option<&Station> {
        self.list.get(id.index())
    }

    pub fn station_mut(&mut self, id: StationId) -> Option<&mut Station> {
        self.list.get_mut(id.index())
    }

    /// The ids of every station, in order.
    pub fn ids(&self) -> impl Iterator<Item = StationId> {
        (0..self.list.len()).map(StationId::from_index)
    }

    /// The stations, in order.
    pub fn into_vec(self) -> Vec<Station> {
        self.list
    }
}

impl From<Vec<Station>> for Stations {
    fn from(list: Vec<Station>) -> Self {
        Stations { list }
    }
}

impl Deref for Stations {
    type Target = [Station];
    fn deref(&self) -> &[Station] {
        &self.list
    }
}

impl DerefMut for Stations {
    fn deref_mut(&mut self) -> &mut [Station] {
        &mut self.list
    }
}

impl<'a> IntoIterator for &'a Stations {
    type Item = &'a Station;
    type IntoIter = std::slice::Iter<'a, Station>;
    fn into_iter(self) -> Self::IntoIter {
        self.list.iter()
    }
}

impl<'a> IntoIterator for &'a mut Stations {
    type Item = &'a mut Station;
    type IntoIter = std::slice::IterMut<'a, Station>;
    fn into_iter(self) -> Self::IntoIter {
        self.list.iter_mut()
    }
}
