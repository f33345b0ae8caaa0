//! The Festo CMMO-ST (`drive::vendors::festo_cmmo_st`): its FHPP register image on Modbus
//! TCP and what the runtime serves of it, its FHPP side on the console (the motion page's
//! FHPP half, its own web server's pages), a master for its FHPP over Modbus TCP, its IO-Link
//! device descriptions (IODD) and its section of the cell file (stepper, axis, Modbus server).

pub mod cell_section;
pub mod fhpp_commands;
pub mod fhpp_console;
pub mod fhpp_master;
pub mod fhpp_motion;
pub mod iodd;
pub mod iodd_command;
pub mod modbus_server;
pub mod web_server;

use crate::web::DevicePages;

/// The web server's page and API (`/cmmo-st/{drive}`, `/api/cmmo-st/{drive}/…`), and the
/// FHPP half of the console's motion page.
pub const WEB_PAGES: DevicePages = DevicePages {
    routes: web_server::routes,
    openapi: <web_server::CmmoStDoc as utoipa::OpenApi>::openapi,
    motion: Some(fhpp_motion::MOTION),
};
