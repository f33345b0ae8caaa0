//! Reading and writing a node's PDO configuration over SDO with the CiA 301 procedure:
//! disable (COB-ID bit 31), parameters, mapping count 0, entries, count n, enable.

use od::AbortCode;

use super::sdo_client::{SdoClient, SdoError};

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Direction {
    Rpdo,
    Tpdo,
}

impl Direction {
    pub fn comm_base(self) -> u16 {
        match self {
            Direction::Rpdo => 0x1400,
            Direction::Tpdo => 0x1800,
        }
    }
}

/// One mapped object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Mapping {
    pub index: u16,
    pub sub: u8,
    pub bits: u8,
}

impl Mapping {
    pub fn to_u32(self) -> u32 {
        (u32::from(self.index) << 16) | (u32::from(self.sub) << 8) | u32::from(self.bits)
    }
    /// `6041:00:16` or `6041:0:16`.
    pub fn parse(s: &str) -> Option<Self> {
        let mut p = s.split(':');
        let index = u16::from_str_radix(p.next()?.trim_start_matches("0x"), 16).ok()?;
        let sub = u8::from_str_radix(p.next()?, 16).ok()?;
        let bits: u8 = p.next()?.parse().ok()?;
        if p.next().is_some() || bits == 0 || bits > 64 {
            return None;
        }
        Some(Mapping { index, sub, bits })
    }
}

/// A PDO as the node reports it.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct PdoInfo {
    pub direction: Direction,
    pub number: u16,
    pub cob_id: u32,
    pub valid: bool,
    pub transmission_type: u8,
    pub inhibit_time_100us: Option<u16>,
    pub event_timer_ms: Option<u16>,
    pub mapping: Vec<Mapping>,
}

fn optional<T>(r: Result<T, SdoError>) -> Result<Option<T>, SdoError> {
    match r {
        Ok(v) => Ok(Some(v)),
        Err(SdoError::Abort(AbortCode::NO_SUB_INDEX | AbortCode::NO_OBJECT)) => Ok(None),
        Err(e) => Err(e),
    }
}

async fn read_uint(c: &mut SdoClient<'_>, index: u16, sub: u8) -> Result<u32, SdoError> {
    let d = c.upload(index, sub).await?;
    let mut b = [0u8; 4];
    for (dst, src) in b.iter_mut().zip(&d) {
        *dst = *src;
    }
    Ok(u32::from_le_bytes(b))
}

/// Reads PDO `number` (1-based); `None` when the node does not have it.
pub async fn read_pdo(
    c: &mut SdoClient<'_>,
    dir: Direction,
    number: u16,
) -> Result<Option<PdoInfo>, SdoError> {
    let comm = dir.comm_base() + number - 1;
    let Some(cob_id) = optional(read_uint(c, comm, 1).await)? else {
        return Ok(None);
    };
    let transmission_type = read_uint(c, comm, 2).await? as u8;
    let inhibit = optional(read_uint(c, comm, 3).await)?.map(|v| v as u16);
    let event = optional(read_uint(c, comm, 5).await)?.map(|v| v as u16);
    let n = read_uint(c, comm + 0x200, 0).await? as u8;
    let mut mapping = Vec::new();
    for sub in 1..=n {
        let v = read_uint(c, comm + 0x200, sub).await?;
        mapping.push(Mapping {
            index: (v >> 16) as u16,
            sub: (v >> 8) as u8,
            bits: v as u8,
        });
    }
    Ok(Some(PdoInfo {
        direction: dir,
        number,
        cob_id,
        valid: cob_id & 0x8000_0000 == 0,
        transmission_type,
        inhibit_time_100us: inhibit.filter(|_| dir == Direction::Tpdo),
        event_timer_ms: event,
        mapping,
    }))
}

/// What to write.
#[derive(Debug, Clone)]
pub struct PdoSetting {
    pub cob_id: u16,
    pub transmission_type: u8,
    pub inhibit_time_100us: Option<u16>,
    pub event_timer_ms: Option<u16>,
    pub mapping: Vec<Mapping>,
    pub enable: bool,
}

/// Writes PDO `number` with the CiA 301 procedure.
pub async fn write_pdo(
    c: &mut SdoClient<'_>,
    dir: Direction,
    number: u16,
    s: &PdoSetting,
) -> Result<(), SdoError> {
    let comm = dir.comm_base() + number - 1;
    let cob = u32::from(s.cob_id & 0x7FF);
    c.download(comm, 1, &(cob | 0x8000_0000).to_le_bytes())
        .await?;
    c.download(comm, 2, &[s.transmission_type]).await?;
    if let Some(t) = s.inhibit_time_100us {
        c.download(comm, 3, &t.to_le_bytes()).await?;
    }
    if let Some(t) = s.event_timer_ms {
        c.download(comm, 5, &t.to_le_bytes()).await?;
    }
    c.download(comm + 0x200, 0, &[0]).await?;
    for (i, m) in s.mapping.iter().enumerate() {
        c.download(comm + 0x200, i as u8 + 1, &m.to_u32().to_le_bytes())
            .await?;
    }
    c.download(comm + 0x200, 0, &[s.mapping.len() as u8])
        .await?;
    if s.enable {
        c.download(comm, 1, &cob.to_le_bytes()).await?;
    }
    Ok(())
}
