use super::*;

pub(crate) async fn lss(cmd: LssCommand) -> Result<(), CommandError> {
    match cmd {
        LssCommand::Fastscan {
            node,
            timeout_ms,
            bus,
        } => {
            if let Some(n) = node {
                check_node(n)?;
            }
            let mut link = connect(&bus).await?;
            let mut m = LssMaster::new(&mut link, Duration::from_millis(timeout_ms));
            let Some(addr) = m.fast_scan().await? else {
                if bus.json {
                    out!("{}", serde_json::json!({"found": false}));
                } else {
                    out!("no unconfigured node answered");
                }
                return Err(CommandError::Lss(LssError::NoResponse(
                    Duration::from_millis(timeout_ms),
                )));
            };
            if let Some(n) = node {
                m.timeout = Duration::from_millis(timeout_ms.max(200));
                m.configure_node_id(n).await?;
                m.store_configuration().await?;
                m.switch_global(false).await?;
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
            if bus.json {
                out!(
                    "{}",
                    serde_json::json!({"found": true, "vendor_id": addr[0], "product_code": addr[1], "revision": addr[2], "serial": addr[3], "node": node})
                );
            } else {
                out!(
                    "found vendor {:08X} product {:08X} revision {:08X} serial {:08X}{}",
                    addr[0],
                    addr[1],
                    addr[2],
                    addr[3],
                    node.map(|n| format!(", now node {n}")).unwrap_or_default()
                );
            }
            Ok(())
        }
        LssCommand::SetNode {
            node,
            timeout_ms,
            bus,
        } => {
            check_node(node)?;
            let mut link = connect(&bus).await?;
            let mut m = LssMaster::new(&mut link, Duration::from_millis(timeout_ms));
            m.switch_global(true).await?;
            m.configure_node_id(node).await?;
            m.store_configuration().await?;
            m.switch_global(false).await?;
            tokio::time::sleep(Duration::from_millis(50)).await;
            Ok(())
        }
    }
}
