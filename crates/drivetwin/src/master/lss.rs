//! LSS master (CiA 305): fastscan for unconfigured nodes, node-ID and bit-timing
//! configuration, store, and the switch-state services.

use std::time::Duration;

use canopen::lss::{cs, LSS_REQUEST_ID, LSS_RESPONSE_ID};
use canopen::CanFrame;

use super::link::{Link, LinkError};

#[derive(Debug, thiserror::Error)]
pub enum LssError {
    #[error("no LSS response within {0:?}")]
    NoResponse(Duration),
    #[error("LSS error {code} (specific {specific}) for command {cs:02X}h")]
    Refused { cs: u8, code: u8, specific: u8 },
    #[error(transparent)]
    Link(#[from] LinkError),
}

pub struct LssMaster<'a> {
    link: &'a mut Link,
    /// How long to wait for an answer; a fastscan bit that does not match gets none, so this
    /// sets the scan's duration.
    pub timeout: Duration,
}

impl<'a> LssMaster<'a> {
    pub fn new(link: &'a mut Link, timeout: Duration) -> Self {
        LssMaster { link, timeout }
    }

    async fn send(&mut self, data: [u8; 8]) -> Result<(), LssError> {
        self.link
            .send(&CanFrame::full(LSS_REQUEST_ID, data))
            .await?;
        Ok(())
    }

    /// Sends and waits for the first answer on 7E4h.
    async fn request(&mut self, data: [u8; 8]) -> Result<Option<[u8; 8]>, LssError> {
        self.send(data).await?;
        let deadline = tokio::time::Instant::now() + self.timeout;
        loop {
            match tokio::time::timeout_at(deadline, self.link.recv()).await {
                Err(_) => return Ok(None),
                Ok(f) => {
                    let f = f?;
                    if f.cob_id() == Some(LSS_RESPONSE_ID) {
                        let mut r = [0u8; 8];
                        for (dst, src) in r.iter_mut().zip(f.payload()) {
                            *dst = *src;
                        }
                        return Ok(Some(r));
                    }
                }
            }
        }
    }

    /// Switch state global: `true` = configuration, `false` = waiting.
    pub async fn switch_global(&mut self, configuration: bool) -> Result<(), LssError> {
        self.send([
            cs::SWITCH_STATE_GLOBAL,
            u8::from(configuration),
            0,
            0,
            0,
            0,
            0,
            0,
        ])
        .await
    }

    async fn configure(&mut self, command: u8, a: u8, b: u8) -> Result<(), LssError> {
        match self.request([command, a, b, 0, 0, 0, 0, 0]).await? {
            None => Err(LssError::NoResponse(self.timeout)),
            Some([c, 0, ..]) if c == command => Ok(()),
            Some([c, code, specific, ..]) => Err(LssError::Refused {
                cs: c,
                code,
                specific,
            }),
        }
    }

    pub async fn configure_node_id(&mut self, node_id: u8) -> Result<(), LssError> {
        self.configure(cs::CONFIGURE_NODE_ID, node_id, 0).await
    }

    pub async fn store_configuration(&mut self) -> Result<(), LssError> {
        self.configure(cs::STORE_CONFIGURATION, 0, 0).await
    }

    pub async fn inquire_node_id(&mut self) -> Result<u8, LssError> {
        match self
            .request([cs::INQUIRE_NODE_ID, 0, 0, 0, 0, 0, 0, 0])
            .await?
        {
            Some([c, id, ..]) if c == cs::INQUIRE_NODE_ID => Ok(id),
            Some(_) | None => Err(LssError::NoResponse(self.timeout)),
        }
    }

    async fn fastscan_step(
        &mut self,
        id: u32,
        bit_check: u8,
        sub: u8,
        next: u8,
    ) -> Result<bool, LssError> {
        let [a, b, c, d] = id.to_le_bytes();
        Ok(matches!(
            self.request([cs::FASTSCAN, a, b, c, d, bit_check, sub, next])
                .await?,
            Some([0x4F, ..])
        ))
    }

    /// Finds one unconfigured node and leaves it in configuration state (CiA 305 §8.4.4).
    /// Returns its LSS address (vendor, product, revision, serial).
    pub async fn fast_scan(&mut self) -> Result<Option<[u32; 4]>, LssError> {
        let mut id = [0u32; 4];
        if !self.fastscan_step(0, 0x80, 0, 0).await? {
            return Ok(None);
        }
        for (sub, part) in (0u8..4).zip(id.iter_mut()) {
            for bit in (0u8..32).rev() {
                if !self.fastscan_step(*part, bit, sub, sub).await? {
                    *part |= 1 << bit;
                }
            }
            let next = (sub + 1) & 3;
            if !self.fastscan_step(*part, 0, sub, next).await? {
                return Ok(None);
            }
        }
        Ok(Some(id))
    }
}
