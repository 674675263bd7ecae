//! The AprilTag families libapriltag ships ([`TagFamily`], whose names and code counts live with
//! the boards): one table of their libapriltag constructors, shared by the detector, the renderer
//! and the board printer, and the tag patterns read from libapriltag's own family data.

use apriltag_sys as sys;

use crate::types::board::TagFamily;

unsafe extern "C" {
    // In Debian's libapriltag 3.3 but missing from apriltag-sys's bindings.
    fn tag36h10_create() -> *mut sys::apriltag_family_t;
    fn tag36h10_destroy(tf: *mut sys::apriltag_family_t);
}

/// A libapriltag family constructor.
pub(crate) type Create = unsafe extern "C" fn() -> *mut sys::apriltag_family_t;
/// A libapriltag family destructor.
pub(crate) type Destroy = unsafe extern "C" fn(*mut sys::apriltag_family_t);

/// One row of the constructor table.
struct FamilyEntry {
    family: TagFamily,
    create: Create,
    destroy: Destroy,
}

/// libapriltag's constructor and destructor of every family, in the order of [`TagFamily::ALL`].
const FAMILIES: [FamilyEntry; 9] = [
    FamilyEntry {
        family: TagFamily::Tag36h11,
        create: sys::tag36h11_create,
        destroy: sys::tag36h11_destroy,
    },
    FamilyEntry {
        family: TagFamily::Tag36h10,
        create: tag36h10_create,
        destroy: tag36h10_destroy,
    },
    FamilyEntry {
        family: TagFamily::Tag25h9,
        create: sys::tag25h9_create,
        destroy: sys::tag25h9_destroy,
    },
    FamilyEntry {
        family: TagFamily::Tag16h5,
        create: sys::tag16h5_create,
        destroy: sys::tag16h5_destroy,
    },
    FamilyEntry {
        family: TagFamily::TagCircle21h7,
        create: sys::tagCircle21h7_create,
        destroy: sys::tagCircle21h7_destroy,
    },
    FamilyEntry {
        family: TagFamily::TagCircle49h12,
        create: sys::tagCircle49h12_create,
        destroy: sys::tagCircle49h12_destroy,
    },
    FamilyEntry {
        family: TagFamily::TagStandard41h12,
        create: sys::tagStandard41h12_create,
        destroy: sys::tagStandard41h12_destroy,
    },
    FamilyEntry {
        family: TagFamily::TagStandard52h13,
        create: sys::tagStandard52h13_create,
        destroy: sys::tagStandard52h13_destroy,
    },
    FamilyEntry {
        family: TagFamily::TagCustom48h12,
        create: sys::tagCustom48h12_create,
        destroy: sys::tagCustom48h12_destroy,
    },
];

/// libapriltag's constructor and destructor of a family.
pub(crate) fn ffi(family: TagFamily) -> (Create, Destroy) {
    // FAMILIES lists the families in the enum's order (checked by a unit test).
    let e = &FAMILIES[family as usize];
    debug_assert_eq!(e.family, family);
    (e.create, e.destroy)
}

/// A family's layout and the cell patterns of some of its tags, read from libapriltag.
#[derive(Clone, Debug, PartialEq)]
pub struct FamilyLayout {
    /// Number of codes (valid ids are 0..ncodes).
    pub ncodes: u32,
    /// Cells across the whole tag pattern.
    pub total_width: u32,
    /// Cells across the square whose edge is the tag size (the black square's outer edge for
    /// the classic families; the black-white border for the others).
    pub width_at_border: u32,
    /// Whether the border is white inside black (tagStandard and tagCircle families).
    pub reversed_border: bool,
}

/// A family as libapriltag holds it, borrowed while it is alive.
struct RawFamily<'a> {
    layout: FamilyLayout,
    codes: &'a [u64],
    nbits: usize,
    bit_x: &'a [u32],
    bit_y: &'a [u32],
}

/// Creates the family in libapriltag, calls `f` with it and frees it. `None` when the
/// constructor fails or the family lacks its code tables.
fn read_family<T>(family: TagFamily, f: impl FnOnce(&RawFamily<'_>) -> T) -> Option<T> {
    let (create, destroy) = ffi(family);
    // SAFETY: the family constructors return a heap-allocated family (or null); it is read only
    // inside this block, while alive, through the counts it states (after checking its tables
    // are not null), and freed with its own destructor.
    unsafe {
        let tf = create();
        if tf.is_null() {
            return None;
        }
        let fam = &*tf;
        let tables = !fam.codes.is_null() && !fam.bit_x.is_null() && !fam.bit_y.is_null();
        let out = tables.then(|| {
            let nbits = fam.nbits as usize;
            f(&RawFamily {
                layout: FamilyLayout {
                    ncodes: fam.ncodes,
                    total_width: fam.total_width.max(0) as u32,
                    width_at_border: fam.width_at_border.max(0) as u32,
                    reversed_border: fam.reversed_border,
                },
                codes: std::slice::from_raw_parts(fam.codes, fam.ncodes as usize),
                nbits,
                bit_x: std::slice::from_raw_parts(fam.bit_x, nbits),
                bit_y: std::slice::from_raw_parts(fam.bit_y, nbits),
            })
        });
        destroy(tf);
        out
    }
}

/// Reads the family from libapriltag and calls `f` with its layout and a cell function.
fn with_family<T>(
    family: TagFamily,
    f: impl FnOnce(&FamilyLayout, &dyn Fn(u32) -> Option<Vec<Vec<bool>>>) -> T,
) -> Option<T> {
    read_family(family, |raw| {
        let layout = &raw.layout;
        let (codes, nbits, bit_x, bit_y) = (raw.codes, raw.nbits, raw.bit_x, raw.bit_y);
        let tw = layout.total_width as usize;
        let wab = layout.width_at_border as usize;
        let cells = |id: u32| -> Option<Vec<Vec<bool>>> {
            let code = *codes.get(id as usize)?;
            if tw == 0 || wab > tw {
                return None;
            }
            // Everything black, then the white ring just outside the border square (classic
            // families) or just inside it (reversed border), then the white data bits.
            let mut black = vec![vec![true; tw]; tw];
            let ring = wab + if layout.reversed_border { 0 } else { 2 };
            let start = (tw as isize - ring as isize) / 2;
            if ring >= 2 && start >= 0 {
                let (s, e) = (start as usize, start as usize + ring - 1);
                #[allow(clippy::needless_range_loop)] // rows and columns of the same ring
                for i in s..=e {
                    black[s][i] = false;
                    black[e][i] = false;
                    black[i][s] = false;
                    black[i][e] = false;
                }
            }
            let border_start = (tw - wab) / 2;
            for i in 0..nbits {
                if (code >> (nbits - 1 - i)) & 1 == 1 {
                    // The families outside the border (tagStandard, tagCircle) store negative
                    // positions in these unsigned fields.
                    let x = bit_x[i] as i32 as isize + border_start as isize;
                    let y = bit_y[i] as i32 as isize + border_start as isize;
                    if (0..tw as isize).contains(&x) && (0..tw as isize).contains(&y) {
                        black[y as usize][x as usize] = false;
                    }
                }
            }
            Some(black)
        };
        f(layout, &cells)
    })
}

/// A family's codes and the cell of each code bit, read from libapriltag: `codes[id]` holds
/// `bits.len()` bits, most significant first; bit `i` (1 = white) sits in the cell column
/// `bits[i].0`, row `bits[i].1` (row 0 at the top), counted from the corner of the
/// `width_at_border` square.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct FamilyCodes {
    pub codes: Vec<u64>,
    pub bits: Vec<(u32, u32)>,
}

/// The codes and bit cells of a family (see [`FamilyCodes`]).
pub(crate) fn family_codes(family: TagFamily) -> Option<FamilyCodes> {
    read_family(family, |raw| FamilyCodes {
        codes: raw.codes.to_vec(),
        bits: raw
            .bit_x
            .iter()
            .zip(raw.bit_y)
            .map(|(&x, &y)| (x, y))
            .collect(),
    })
}

/// The layout of a family, from libapriltag.
pub fn family_layout(family: TagFamily) -> Option<FamilyLayout> {
    with_family(family, |l, _| l.clone())
}

/// The cells of a tag (`true` = black): the full tag pattern including its border, row 0 at the
/// top, in the canonical orientation (as libapriltag's `apriltag_to_image` draws it). `None` for
/// an id the family does not have.
pub fn tag_cells(family: TagFamily, id: u32) -> Option<Vec<Vec<bool>>> {
    with_family(family, |_, cells| cells(id)).flatten()
}

/// Black/white cells of one tag, row 0 at the top (`true` = black).
pub type TagCells = Vec<Vec<bool>>;

/// The cells of several tags of one family at once (reads the family once).
pub fn tags_cells(family: TagFamily, ids: &[u32]) -> Option<(FamilyLayout, Vec<Option<TagCells>>)> {
    with_family(family, |l, cells| {
        (l.clone(), ids.iter().map(|&i| cells(i)).collect())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_rows_follow_the_enum_and_names_are_unique() {
        for (i, f) in TagFamily::ALL.iter().enumerate() {
            assert_eq!(FAMILIES[i].family, *f);
            assert_eq!(*f as usize, i);
            assert_eq!(TagFamily::from_name(f.name()), Some(*f));
        }
    }
}
