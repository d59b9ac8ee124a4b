//! Program download on a duocan node (`duocan::cia302::program`): the rules of 0x1F50/0x1F51
//! over a program store with staging, as a bus client sees them (abort codes, 0x1F57), and a
//! property: whatever sequence of commands and downloads arrives, the program in control
//! changes only to a verified image followed by start.

use duocan::cia302::program::{FlashError, ProgramDictionary, ProgramStore};
use duocan::od::{comm, DynamicDictionary, ObjectDictionary};
use duocan::AbortCode;
use proptest::prelude::*;

/// Stages images whose first byte is not 0xFF; an image is identified by its length.
#[derive(Default)]
struct Store {
    running: u32,
    staged: Option<u32>,
    on: bool,
    clear_fails: bool,
}

impl ProgramStore for Store {
    fn capacity(&self) -> u32 {
        64
    }
    fn stop(&mut self) {
        self.on = false;
    }
    fn run(&mut self) {
        self.on = true;
    }
    fn clear(&mut self) -> Result<(), FlashError> {
        if self.clear_fails {
            return Err(FlashError::Secured);
        }
        self.staged = None;
        Ok(())
    }
    fn stage(&mut self, image: &[u8]) -> Result<(), FlashError> {
        if image.first() == Some(&0xFF) {
            return Err(FlashError::WriteError);
        }
        self.staged = Some(image.len() as u32);
        Ok(())
    }
    fn activate(&mut self) -> Result<(), FlashError> {
        self.running = self.staged.take().ok_or(FlashError::NoValidProgram)?;
        Ok(())
    }
    fn identification(&self) -> u32 {
        self.running
    }
}

type Od = ProgramDictionary<DynamicDictionary, Store>;

fn od() -> Od {
    let store = Store {
        running: 1,
        on: true,
        ..Store::default()
    };
    ProgramDictionary::new(comm::standard_dictionary(4, Default::default()), store)
}

fn cmd(od: &mut Od, c: u8) -> Result<(), AbortCode> {
    od.write(0x1F51, 1, &[c])
}

#[test]
fn the_rules_as_a_client_sees_them() {
    let mut od = od();
    // While running: no clear, no download.
    assert_eq!(cmd(&mut od, 3), Err(AbortCode::DEVICE_STATE));
    assert_eq!(od.write(0x1F50, 1, &[1; 8]), Err(AbortCode::DEVICE_STATE));
    assert_eq!(cmd(&mut od, 4), Err(AbortCode::VALUE_RANGE));
    cmd(&mut od, 0).unwrap();
    assert_eq!(od.get_u32(0x1F51, 1), Some(0));
    // Not cleared: refused, 0x1F57 says why (code 4).
    assert_eq!(od.write(0x1F50, 1, &[1; 8]), Err(AbortCode::CANNOT_STORE));
    assert_eq!(od.get_u32(0x1F57, 1), Some(4 << 1));
    cmd(&mut od, 3).unwrap();
    assert_eq!(od.get_u32(0x1F57, 1), Some(0));
    // Above the capacity: refused before the store sees it.
    assert_eq!(
        od.write(0x1F50, 1, &[1; 65]),
        Err(AbortCode::LENGTH_TOO_HIGH)
    );
    // A write the store refuses: nothing staged, start runs the old program.
    assert_eq!(
        od.write(0x1F50, 1, &[0xFF; 8]),
        Err(AbortCode::CANNOT_STORE)
    );
    assert_eq!(od.get_u32(0x1F57, 1), Some(5 << 1));
    cmd(&mut od, 1).unwrap();
    assert_eq!((od.get_u32(0x1F56, 1), od.store().on), (Some(1), true));
    // A verified one, then reset: dropped.
    cmd(&mut od, 0).unwrap();
    cmd(&mut od, 3).unwrap();
    od.write(0x1F50, 1, &[1; 9]).unwrap();
    cmd(&mut od, 2).unwrap();
    cmd(&mut od, 1).unwrap();
    assert_eq!(od.get_u32(0x1F56, 1), Some(1));
    // A verified one, then start: in control.
    cmd(&mut od, 0).unwrap();
    cmd(&mut od, 3).unwrap();
    od.write(0x1F50, 1, &[1; 9]).unwrap();
    assert_eq!(od.get_u32(0x1F56, 1), Some(1));
    cmd(&mut od, 1).unwrap();
    assert_eq!(od.get_u32(0x1F56, 1), Some(9));
    // Program data is write only; the identification and status read only.
    assert_eq!(od.read(0x1F50, 1), Err(AbortCode::WRITE_ONLY));
    assert_eq!(od.write(0x1F56, 1, &[0; 4]), Err(AbortCode::READ_ONLY));
    assert_eq!(od.write(0x1F57, 1, &[0; 4]), Err(AbortCode::READ_ONLY));
    assert_eq!(od.get(0x1F51, 2).map(|_| ()), Err(AbortCode::NO_SUB_INDEX));
    // The rest of the dictionary is the inner one's.
    assert_eq!(od.len(), od.inner().len() + 8);
    assert!(od.get(comm::DEVICE_TYPE, 0).is_ok());
    // A clear the store refuses: reported, and a download still needs a clear.
    cmd(&mut od, 0).unwrap();
    od.store_mut().clear_fails = true;
    assert_eq!(cmd(&mut od, 3), Err(AbortCode::CANNOT_STORE));
    assert_eq!(od.get_u32(0x1F57, 1), Some(7 << 1));
    assert_eq!(od.write(0x1F50, 1, &[1; 3]), Err(AbortCode::CANNOT_STORE));
}

#[derive(Clone, Debug)]
enum Op {
    Cmd(u8),
    Image(u8, u8),
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        (0u8..6).prop_map(Op::Cmd),
        (1u8..80, any::<u8>()).prop_map(|(len, first)| Op::Image(len, first)),
    ]
}

proptest! {
    #[test]
    fn the_program_changes_only_to_a_verified_image_followed_by_start(
        ops in prop::collection::vec(op(), 0..40)
    ) {
        let mut od = od();
        // The model: the last image accepted since the last clear, if any.
        let mut pending: Option<u32> = None;
        for op in ops {
            let before = od.get_u32(0x1F56, 1).unwrap();
            match op {
                Op::Cmd(c) => {
                    let r = cmd(&mut od, c);
                    let after = od.get_u32(0x1F56, 1).unwrap();
                    if c == 1 && r.is_ok() {
                        prop_assert_eq!(after, pending.take().unwrap_or(before));
                    } else {
                        prop_assert_eq!(after, before);
                    }
                    if matches!(c, 2 | 3) && r.is_ok() {
                        pending = None;
                    }
                }
                Op::Image(len, first) => {
                    let image = vec![first; len as usize];
                    if od.write(0x1F50, 1, &image).is_ok() {
                        prop_assert!(len <= 64 && first != 0xFF);
                        pending = Some(len as u32);
                    } else if len <= 64 && od.get_u32(0x1F51, 1) == Some(0) {
                        // An image refused by the store (or for want of a clear) drops what
                        // was staged; one refused for its length never reached it.
                        pending = None;
                    }
                    prop_assert_eq!(od.get_u32(0x1F56, 1).unwrap(), before);
                }
            }
        }
    }
}
