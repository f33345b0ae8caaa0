//! SDO client (CiA 301 §7.2.4): expedited and segmented upload and download, one transfer at
//! a time, answering the server's aborts and timing out like python-canopen does.

use std::time::Duration;

use canopen::CanFrame;
use od::AbortCode;

use super::link::{Link, LinkError};

#[derive(Debug, thiserror::Error)]
pub enum SdoError {
    #[error("SDO abort {0}")]
    Abort(AbortCode),
    #[error("no SDO response from node {node} within {timeout:?}")]
    Timeout { node: u8, timeout: Duration },
    #[error("unexpected SDO response {0:02X?}")]
    Protocol([u8; 8]),
    #[error(transparent)]
    Link(#[from] LinkError),
}

pub struct SdoClient<'a> {
    link: &'a mut Link,
    node: u8,
    timeout: Duration,
}

impl<'a> SdoClient<'a> {
    pub fn new(link: &'a mut Link, node: u8, timeout: Duration) -> Self {
        SdoClient {
            link,
            node,
            timeout,
        }
    }

    fn rx_id(&self) -> u16 {
        0x600 + u16::from(self.node)
    }

    async fn request(&mut self, data: [u8; 8]) -> Result<[u8; 8], SdoError> {
        self.link.send(&CanFrame::full(self.rx_id(), data)).await?;
        let tx = 0x580 + u32::from(self.node);
        let deadline = tokio::time::Instant::now() + self.timeout;
        loop {
            let f = tokio::time::timeout_at(deadline, self.link.recv())
                .await
                .map_err(|_| SdoError::Timeout {
                    node: self.node,
                    timeout: self.timeout,
                })??;
            if f.id == tx && !f.extended && !f.rtr {
                let mut r = [0u8; 8];
                let p = f.payload();
                if let Some(dst) = r.get_mut(..p.len()) {
                    dst.copy_from_slice(p);
                }
                if r[0] == 0x80 {
                    return Err(SdoError::Abort(AbortCode(u32::from_le_bytes([
                        r[4], r[5], r[6], r[7],
                    ]))));
                }
                return Ok(r);
            }
        }
    }

    async fn abort(&mut self, index: u16, sub: u8, code: AbortCode) {
        let [i0, i1] = index.to_le_bytes();
        let [c0, c1, c2, c3] = code.0.to_le_bytes();
        let _ = self
            .link
            .send(&CanFrame::full(
                self.rx_id(),
                [0x80, i0, i1, sub, c0, c1, c2, c3],
            ))
            .await;
    }

    /// Reads a whole value.
    pub async fn upload(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, SdoError> {
        let [i0, i1] = index.to_le_bytes();
        let r = self.request([0x40, i0, i1, sub, 0, 0, 0, 0]).await?;
        if r[0] & 0xE0 != 0x40 {
            return Err(SdoError::Protocol(r));
        }
        if r[0] & 0x02 != 0 {
            let n = if r[0] & 0x01 != 0 {
                4 - usize::from((r[0] >> 2) & 3)
            } else {
                4
            };
            return Ok(r.get(4..4 + n).unwrap_or(&[]).to_vec());
        }
        let size =
            (r[0] & 0x01 != 0).then(|| u32::from_le_bytes([r[4], r[5], r[6], r[7]]) as usize);
        let mut data = Vec::with_capacity(size.unwrap_or(64).min(1 << 20));
        let mut toggle = 0u8;
        loop {
            let r = self
                .request([0x60 | (toggle << 4), 0, 0, 0, 0, 0, 0, 0])
                .await?;
            if r[0] & 0xE0 != 0 || (r[0] >> 4) & 1 != toggle {
                self.abort(index, sub, AbortCode::TOGGLE_BIT).await;
                return Err(SdoError::Protocol(r));
            }
            let n = 7 - usize::from((r[0] >> 1) & 7);
            data.extend_from_slice(r.get(1..1 + n).unwrap_or(&[]));
            if r[0] & 0x01 != 0 {
                break;
            }
            toggle ^= 1;
        }
        if let Some(size) = size {
            if size != data.len() {
                return Err(SdoError::Protocol(r));
            }
        }
        Ok(data)
    }

    /// Writes a whole value: expedited up to 4 bytes, segmented above.
    pub async fn download(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoError> {
        let [i0, i1] = index.to_le_bytes();
        if (1..=4).contains(&data.len()) {
            let mut req = [
                0x23 | (((4 - data.len()) as u8) << 2),
                i0,
                i1,
                sub,
                0,
                0,
                0,
                0,
            ];
            if let Some(dst) = req.get_mut(4..4 + data.len()) {
                dst.copy_from_slice(data);
            }
            let r = self.request(req).await?;
            return if r[0] == 0x60 {
                Ok(())
            } else {
                Err(SdoError::Protocol(r))
            };
        }
        let [s0, s1, s2, s3] = (data.len() as u32).to_le_bytes();
        let r = self.request([0x21, i0, i1, sub, s0, s1, s2, s3]).await?;
        if r[0] != 0x60 {
            return Err(SdoError::Protocol(r));
        }
        let mut toggle = 0u8;
        let chunks: Vec<&[u8]> = if data.is_empty() {
            vec![&[]]
        } else {
            data.chunks(7).collect()
        };
        let count = chunks.len();
        for (i, chunk) in chunks.into_iter().enumerate() {
            let last = i + 1 == count;
            let mut req = [0u8; 8];
            req[0] = (toggle << 4) | (((7 - chunk.len()) as u8) << 1) | u8::from(last);
            if let Some(dst) = req.get_mut(1..1 + chunk.len()) {
                dst.copy_from_slice(chunk);
            }
            let r = self.request(req).await?;
            if r[0] & 0xE0 != 0x20 {
                return Err(SdoError::Protocol(r));
            }
            toggle ^= 1;
        }
        Ok(())
    }
}
