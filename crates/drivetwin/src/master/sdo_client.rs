//! The master's SDO client over a bus link: `canopen`'s sans-IO client (CiA 301 §7.2.4)
//! decides each request, this moves the frames and times each answer out like python-canopen
//! does.

use std::time::Duration;

use canopen::sdo_client::{self as sdo, Progress, SdoClientError};
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
    transfer: sdo::SdoClient,
}

impl From<SdoClientError> for SdoError {
    fn from(e: SdoClientError) -> Self {
        match e {
            SdoClientError::Abort(code) => SdoError::Abort(code),
            SdoClientError::Unexpected { response, .. } | SdoClientError::Size { response, .. } => {
                SdoError::Protocol(response)
            }
            SdoClientError::Idle => SdoError::Protocol([0; 8]),
        }
    }
}

impl<'a> SdoClient<'a> {
    pub fn new(link: &'a mut Link, node: u8, timeout: Duration) -> Self {
        SdoClient {
            link,
            node,
            timeout,
            transfer: sdo::SdoClient::new(),
        }
    }

    fn rx_id(&self) -> u16 {
        0x600 + u16::from(self.node)
    }

    async fn send(&mut self, data: [u8; 8]) -> Result<(), LinkError> {
        self.link.send(&CanFrame::full(self.rx_id(), data)).await
    }

    /// Sends a request and waits for the node's response (8 bytes, zero-padded).
    async fn request(&mut self, data: [u8; 8]) -> Result<[u8; 8], SdoError> {
        self.send(data).await?;
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
                for (dst, src) in r.iter_mut().zip(f.payload()) {
                    *dst = *src;
                }
                return Ok(r);
            }
        }
    }

    /// Runs the transfer `first` started: each response gives the next request, an upload's
    /// bytes are gathered; an abort the client ends the transfer with is sent.
    async fn run(&mut self, first: [u8; 8], value: &[u8]) -> Result<Vec<u8>, SdoError> {
        let mut data = Vec::new();
        let mut request = first;
        loop {
            let response = self.request(request).await?;
            match self.transfer.on_response(&response, value) {
                Ok(Progress::Next {
                    data: d,
                    request: next,
                }) => {
                    data.extend_from_slice(d);
                    request = next;
                }
                Ok(Progress::Done { data: d }) => {
                    data.extend_from_slice(d);
                    return Ok(data);
                }
                Err(e) => {
                    if let SdoClientError::Unexpected {
                        abort: Some(abort), ..
                    } = e
                    {
                        let _ = self.send(abort).await;
                    }
                    return Err(e.into());
                }
            }
        }
    }

    /// Reads a whole value.
    pub async fn upload(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, SdoError> {
        let first = self.transfer.upload(index, sub);
        self.run(first, &[]).await
    }

    /// Writes a whole value: expedited up to 4 bytes, segmented above.
    pub async fn download(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoError> {
        let first = self.transfer.download(index, sub, data);
        self.run(first, data).await.map(|_| ())
    }
}
