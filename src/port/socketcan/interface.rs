//! What sysfs tells of an interface (present, up, its MTU), the errors that say how to fix
//! one, and error frames written on one (how tests inject controller errors on a vcan).

use super::CANFD_MTU;
use crate::port::{PortError, PortErrorKind};
use socketcan::{CanErrorFrame, CanFrame, Socket as _};
use std::io;

const IFF_UP: u32 = 0x1;

/// Link state of a network interface as sysfs shows it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkState {
    /// No such interface.
    Missing,
    /// Present, administratively down.
    Down,
    /// Present and up.
    Up,
}

/// Reads `/sys/class/net/IFNAME/flags`. Names that are not interface names are `Missing`.
pub fn link_state(ifname: &str) -> LinkState {
    let valid = !ifname.is_empty()
        && ifname.len() < 16
        && !ifname.contains('/')
        && ifname != "."
        && ifname != "..";
    if !valid {
        return LinkState::Missing;
    }
    match std::fs::read_to_string(format!("/sys/class/net/{ifname}/flags")) {
        Ok(s) => {
            let flags = u32::from_str_radix(s.trim().trim_start_matches("0x"), 16).unwrap_or(0);
            if flags & IFF_UP != 0 {
                LinkState::Up
            } else {
                LinkState::Down
            }
        }
        Err(_) => LinkState::Missing,
    }
}

/// `IFF_ECHO` (linux/if.h): the interface's driver echoes each frame once it was sent.
const IFF_ECHO: u32 = 0x4_0000;

/// Whether the driver of `ifname` echoes frames once they were on the bus (`IFF_ECHO` in
/// `/sys/class/net/IFNAME/flags`): a CAN controller's driver does it when the frame was
/// transmitted (acknowledged by a node on its bus); without it the kernel echoes a frame as it
/// is handed to the driver, which confirms nothing. vcan echoes in its driver when loaded with
/// `echo=1` (it has no bus: every frame is on it at once).
pub(super) fn echoes(ifname: &str) -> bool {
    std::fs::read_to_string(format!("/sys/class/net/{ifname}/flags"))
        .ok()
        .and_then(|s| u32::from_str_radix(s.trim().trim_start_matches("0x"), 16).ok())
        .is_some_and(|flags| flags & IFF_ECHO != 0)
}

/// The MTU of `ifname` as sysfs shows it (`None` if it cannot be read).
pub fn interface_mtu(ifname: &str) -> Option<usize> {
    if link_state(ifname) == LinkState::Missing {
        return None;
    }
    std::fs::read_to_string(format!("/sys/class/net/{ifname}/mtu"))
        .ok()?
        .trim()
        .parse()
        .ok()
}

/// The error of an interface that carries no CAN FD frames (its MTU is `mtu`, not 72).
pub(super) fn not_fd(ifname: &str, mtu: Option<usize>) -> PortError {
    let mtu = mtu.map_or_else(|| "an unreadable MTU".to_owned(), |m| format!("MTU {m}"));
    PortError::new(
        ifname,
        PortErrorKind::Config,
        format!(
            "interface {ifname} has {mtu}, not the CAN FD MTU {CANFD_MTU}: it carries no CAN FD frames \
             (a vcan: `ip link set {ifname} mtu {CANFD_MTU}`; a CAN controller: \
             `ip link set {ifname} type can bitrate … dbitrate … fd on`)"
        ),
    )
}

/// Writes an error frame (`bits` | `CAN_ERR_FLAG`, `data`) on `ifname`: how tests inject
/// controller errors on a vcan interface, which has no controller of its own.
pub fn inject_error_frame(ifname: &str, bits: u32, data: &[u8]) -> io::Result<()> {
    let sock = socketcan::CanSocket::open(ifname)?;
    let ef = CanErrorFrame::new_error(bits, data)
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e.to_string()))?;
    sock.write_frame(&CanFrame::Error(ef))
}
