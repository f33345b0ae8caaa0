//! The Kinco FD3 / CD3 (`drive::vendors::kinco`): its LED panel on the web console and a
//! master for its RS232 telegrams.

pub mod panel_page;
pub mod rs232_commands;
pub mod rs232_master;

use crate::web::DevicePages;

/// The panel's REST API (`/api/drives/{drive}/panel`).
pub const WEB_PAGES: DevicePages = DevicePages {
    routes: panel_page::routes,
    openapi: <panel_page::PanelDoc as utoipa::OpenApi>::openapi,
};
