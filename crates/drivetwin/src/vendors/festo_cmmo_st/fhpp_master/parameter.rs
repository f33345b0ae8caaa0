//! PNU read and write through the Enhanced Festo Parameter Channel (EFPC, I/O bytes 9…16,
//! CMMO-ST manual App. C), with the wire codec of [`drive::vendors::festo_cmmo_st::fhpp::parameter_channel`].
//!
//! The procedure of C.3.2: the zero request ("no task", ReqID 0) until the drive answers
//! "no response" (ResID 0), so an old answer cannot be taken for the new one; then the job
//! until the drive answers "parameter transferred" (ResID 5) or an error (ResID 7, Tab. C.7
//! code in the PWE); then the zero request again, which leaves the channel idle for the next
//! master. The telegram keeps cycling (FC 0x17 with 8 registers) throughout.

use std::time::Duration;

use drive::vendors::festo_cmmo_st::fhpp::parameter_channel::{
    res_id, ParameterRequest, ParameterResponse, Request, MODE_PARAMETER,
};

use super::{FhppError, FhppMaster};

impl FhppMaster {
    /// Reads PNU `pnu`, subindex `subindex`: the 32-bit PWE as sent (sign-extended for signed
    /// types).
    pub async fn read_parameter(
        &mut self,
        pnu: u16,
        subindex: u8,
        timeout: Duration,
    ) -> Result<u32, FhppError> {
        self.parameter_job(ParameterRequest::Read { pnu, subindex }, timeout)
            .await
    }

    /// Writes `value` (the PWE) to PNU `pnu`, subindex `subindex`; returns the PWE the drive
    /// echoes.
    pub async fn write_parameter(
        &mut self,
        pnu: u16,
        subindex: u8,
        value: u32,
        timeout: Duration,
    ) -> Result<u32, FhppError> {
        self.parameter_job(
            ParameterRequest::Write {
                pnu,
                subindex,
                value,
            },
            timeout,
        )
        .await
    }

    async fn parameter_job(
        &mut self,
        job: ParameterRequest,
        timeout: Duration,
    ) -> Result<u32, FhppError> {
        const CMD: &str = "pnu";
        if !self.config.parameter_channel {
            return Err(FhppError::NoParameterChannel);
        }
        let deadline = tokio::time::Instant::now() + timeout;
        self.zero_request(timeout).await?;
        self.set_fpc_output(Request::Parameter(job).encode());
        let (pnu, subindex) = (job.pnu(), job.subindex());
        let answer = |fpc: &[u8; 8]| match ParameterResponse::decode(fpc) {
            Ok(ParameterResponse::Value {
                pnu: p,
                subindex: s,
                value,
            }) if (p, s) == (pnu, subindex) => Some(Ok(value)),
            Ok(ParameterResponse::Error {
                pnu: p,
                subindex: s,
                code,
            }) if (p, s) == (pnu, subindex) => Some(Err(code)),
            _ => None,
        };
        let rest = deadline.saturating_duration_since(tokio::time::Instant::now());
        self.wait_fpc(
            CMD,
            "parameter transferred (FPCS ResID 5 or 7)",
            rest,
            |f| answer(f).is_some(),
        )
        .await?;
        let result = answer(&self.fpc_input());
        // C.3.2: the zero request between two jobs (and after the last one).
        self.zero_request(timeout).await?;
        match result {
            Some(Ok(value)) => Ok(value),
            Some(Err(code)) => Err(FhppError::Parameter {
                pnu,
                subindex,
                code,
            }),
            None => Err(FhppError::Protocol("the parameter answer changed")),
        }
    }

    /// "No task" until the drive answers "no response" (C.3.2 step 3).
    async fn zero_request(&mut self, timeout: Duration) -> Result<(), FhppError> {
        self.set_fpc_output(
            Request::NoTask {
                mode: MODE_PARAMETER,
            }
            .encode(),
        );
        self.wait_fpc("pnu", "no response (FPCS ResID 0)", timeout, |f| {
            f[0] & 0x0F == res_id::NONE
        })
        .await
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_are_the_spec_frames() {
        // FHPP-FPC-01 (fhpp §8.2 c): read PNU 1041:1 → FPCC 16h, sub 1, PNU 04 11, PWE 0.
        assert_eq!(
            Request::Parameter(ParameterRequest::Read {
                pnu: 1041,
                subindex: 1
            })
            .encode(),
            [0x16, 0x01, 0x04, 0x11, 0, 0, 0, 0]
        );
        // FHPP-FPC-03 (§8.2 d): write PNU 127:2 = 1 → 18 02 00 7F 00 00 00 01.
        assert_eq!(
            Request::Parameter(ParameterRequest::Write {
                pnu: 127,
                subindex: 2,
                value: 1
            })
            .encode(),
            [0x18, 0x02, 0x00, 0x7F, 0, 0, 0, 1]
        );
        // FHPP-FPC-02: the zero request.
        assert_eq!(
            Request::NoTask {
                mode: MODE_PARAMETER
            }
            .encode(),
            [0x10, 0, 0, 0, 0, 0, 0, 0]
        );
    }
}
