//! The particle state as structure-of-arrays, every field declared once.
//!
//! The table in [`particle_fields!`] below is the only place a particle array is named: the
//! struct, `push`, `permute`, the length check after a checkpoint is read, the VTU columns
//! and the VTU reader all follow from it (as SPlisHSPlasH's field registry does). A new field
//! is one line there.

use super::vector::Vector;
use serde::{Deserialize, Serialize};

/// What a particle is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[repr(u8)]
pub enum Kind {
    /// A fluid particle: moves, carries pressure.
    #[default]
    Fluid = 0,
    /// The wall layer next to the fluid: fixed, carries pressure (a PPE unknown).
    Wall = 1,
    /// Dummy layers behind the wall: fixed, only complete the number density.
    Dummy = 2,
}

/// Marker for "no index" in `u32` index arrays.
pub const NONE: u32 = u32::MAX;

/// Marker for particles outside any named group.
pub const NO_GROUP: u16 = u16::MAX;

/// Where a field goes in a VTU file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Vtu {
    /// The point coordinates (`<Points>`).
    Points,
    /// A point-data array of this name.
    Data(&'static str),
    /// Not written (internal bookkeeping, restored from checkpoints only).
    Internal,
}

/// One VTU column of a particle field: its VTK type, components and raw little-endian bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct Column {
    /// Array name (`Points` for the coordinates).
    pub name: &'static str,
    /// VTK type name (`Float64`, `Int32`, `UInt8`).
    pub vtk_type: &'static str,
    /// Components per particle.
    pub components: usize,
    /// The values, little-endian.
    pub bytes: Vec<u8>,
}

/// How one element type is stored in a VTU column and read back from its values.
pub trait ColumnValue: Sized + Copy {
    /// VTK type name.
    const VTK_TYPE: &'static str;
    /// Components per particle in the file.
    const COMPONENTS: usize;
    /// Appends the value's components, little-endian.
    fn put(&self, out: &mut Vec<u8>);
    /// The value from its components as read back (numbers); `None` when out of range.
    fn from_components(c: &[f64]) -> Option<Self>;
}

impl ColumnValue for f64 {
    const VTK_TYPE: &'static str = "Float64";
    const COMPONENTS: usize = 1;
    fn put(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.to_le_bytes());
    }
    fn from_components(c: &[f64]) -> Option<Self> {
        c.first().copied()
    }
}

/// Vectors are written with three components (VTK's convention), zero-padded in 2D.
impl<const D: usize> ColumnValue for Vector<D> {
    const VTK_TYPE: &'static str = "Float64";
    const COMPONENTS: usize = 3;
    fn put(&self, out: &mut Vec<u8>) {
        for k in 0..3 {
            let v = if k < D { self.0[k] } else { 0.0 };
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    fn from_components(c: &[f64]) -> Option<Self> {
        Vector::from_slice(c.get(..D)?)
    }
}

/// Integers that fit an `Int32` column.
macro_rules! int_column {
    ($($t:ty),*) => {$(
        impl ColumnValue for $t {
            const VTK_TYPE: &'static str = "Int32";
            const COMPONENTS: usize = 1;
            fn put(&self, out: &mut Vec<u8>) {
                out.extend_from_slice(&(*self as i32).to_le_bytes());
            }
            fn from_components(c: &[f64]) -> Option<Self> {
                let v = *c.first()?;
                (v >= <$t>::MIN as f64 && v <= <$t>::MAX as f64 && v.fract() == 0.0)
                    .then_some(v as $t)
            }
        }
    )*};
}
int_column!(u16, u32);

impl ColumnValue for Kind {
    const VTK_TYPE: &'static str = "Int32";
    const COMPONENTS: usize = 1;
    fn put(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&(*self as i32).to_le_bytes());
    }
    fn from_components(c: &[f64]) -> Option<Self> {
        match *c.first()? as i64 {
            0 => Some(Kind::Fluid),
            1 => Some(Kind::Wall),
            2 => Some(Kind::Dummy),
            _ => None,
        }
    }
}

impl ColumnValue for bool {
    const VTK_TYPE: &'static str = "UInt8";
    const COMPONENTS: usize = 1;
    fn put(&self, out: &mut Vec<u8>) {
        out.push(*self as u8);
    }
    fn from_components(c: &[f64]) -> Option<Self> {
        Some(*c.first()? != 0.0)
    }
}

/// A new particle: the values `push` takes; every other field starts at its default.
#[derive(Clone, Copy, Debug)]
pub struct NewParticle<const D: usize> {
    /// Position (m).
    pub position: Vector<D>,
    /// Velocity (m/s).
    pub velocity: Vector<D>,
    /// Fluid, wall or dummy.
    pub kind: Kind,
    /// Phase index.
    pub phase: u16,
    /// Density (kg/m^3).
    pub density: f64,
}

/// Declares the particle fields: `name: type = initial value (from the new particle and its
/// index) => VTU placement`, and `, particle_index` for fields that hold particle indices
/// (remapped when the particles are reordered).
macro_rules! particle_fields {
    (|$new:ident, $index:ident| $(
        $(#[doc = $doc:expr])*
        $name:ident : $ty:ty = $init:expr => $vtu:expr $(, $remap:ident)?;
    )*) => {
        /// All particles of a simulation, one array per quantity (see the module comment).
        #[derive(Clone, Debug, Default, Serialize, Deserialize)]
        pub struct Particles<const D: usize> {
            $( $(#[doc = $doc])* pub $name: Vec<$ty>, )*
        }

        impl<const D: usize> Particles<D> {
            /// Names of every field, in declaration order.
            pub const FIELD_NAMES: &'static [&'static str] = &[$(stringify!($name)),*];

            /// Appends one particle; fields other than those of `new` take their initial value.
            pub fn push(&mut self, $new: NewParticle<D>) {
                let $index = self.position.len() as u32;
                $( self.$name.push($init); )*
            }

            /// Keeps the particles whose `keep` entry is true, in order; particle indices
            /// held in fields are remapped (one pointing to a removed particle becomes
            /// [`NONE`]). Returns the number removed.
            pub fn retain(&mut self, keep: &[bool]) -> usize {
                let mut inverse = vec![NONE; keep.len()];
                let mut kept = 0u32;
                for (old, &k) in keep.iter().enumerate() {
                    if k {
                        inverse[old] = kept;
                        kept += 1;
                    }
                }
                $(
                    let mut flags = keep.iter();
                    self.$name.retain(|_| *flags.next().unwrap_or(&true));
                    $( stringify!($remap); remap_indices(&mut self.$name, &inverse); )?
                )*
                keep.len() - kept as usize
            }

            /// Reorders every array by `order` (new index -> old index); index fields are
            /// remapped to the new numbering.
            pub fn permute(&mut self, order: &[u32]) {
                self.permute_into(order, &mut SpareArrays::default(), &mut Vec::new());
            }

            /// [`Self::permute`], each array gathered into a spare array of `spare` and the
            /// old one given back to it, the inverse order built in `inverse`: once they have
            /// grown, nothing is allocated.
            pub fn permute_into(
                &mut self,
                order: &[u32],
                spare: &mut SpareArrays<D>,
                inverse: &mut Vec<u32>,
            ) {
                inverse.clear();
                inverse.resize(order.len(), 0);
                for (new, &old) in order.iter().enumerate() {
                    inverse[old as usize] = new as u32;
                }
                $(
                    {
                        use rayon::prelude::*;
                        let mut out: Vec<$ty> = spare.take();
                        let field = &self.$name;
                        order
                            .par_iter()
                            .map(|&o| field[o as usize])
                            .collect_into_vec(&mut out);
                        spare.give(std::mem::replace(&mut self.$name, out));
                    }
                    $( stringify!($remap); remap_indices(&mut self.$name, inverse); )?
                )*
            }

            /// Numbers per particle in [`Self::pack`].
            pub const fn packed_width() -> usize {
                0 $( + <$ty as Packed>::WIDTH )*
            }

            /// Appends particle `i`'s fields as numbers (to send it to another process);
            /// fields holding particle indices carry the ids they point to instead.
            pub fn pack(&self, i: usize, out: &mut Vec<f64>) {
                $(
                    #[allow(unused_mut)]
                    let mut v = self.$name[i];
                    $( stringify!($remap); v = id_at(&self.id, v); )?
                    v.pack(out);
                )*
            }

            /// Appends a particle from a row of [`Self::pack`]; fields holding particle
            /// indices keep the ids until [`Self::ids_to_indices`]. `None` when the row is
            /// too short or a value is out of range.
            pub fn push_packed(&mut self, row: &[f64]) -> Option<()> {
                let mut at = 0;
                $(
                    let w = <$ty as Packed>::WIDTH;
                    let v = <$ty as Packed>::unpack(row.get(at..at + w)?)?;
                    at += w;
                    self.$name.push(v);
                )*
                let _ = at;
                Some(())
            }

            /// Turns the ids held in index fields (after [`Self::push_packed`]) into the
            /// indices of the particles with those ids here, [`NONE`] where there is none.
            pub fn ids_to_indices(&mut self) {
                let index: std::collections::HashMap<u32, u32> =
                    self.id.iter().enumerate().map(|(k, &id)| (id, k as u32)).collect();
                $( $(
                    stringify!($remap);
                    for x in &mut self.$name {
                        if *x != NONE {
                            *x = index.get(x).copied().unwrap_or(NONE);
                        }
                    }
                )? )*
            }

            /// Makes `self` a copy of `other`, reusing the memory of `self`'s arrays.
            pub fn copy_from(&mut self, other: &Self) {
                $( self.$name.clone_from(&other.$name); )*
            }

            /// The first field whose length differs from the particle count, if any.
            pub fn inconsistent_field(&self) -> Option<&'static str> {
                let n = self.len();
                $( if self.$name.len() != n { return Some(stringify!($name)); } )*
                None
            }

            /// The VTU columns of every written field.
            pub fn columns(&self) -> Vec<Column> {
                let mut out = Vec::new();
                $( if let Some(c) = column(&self.$name, $vtu) { out.push(c); } )*
                out
            }

            /// Fills the fields from VTU arrays (`(name, values)`, `Points` for the
            /// coordinates). Fields without an array keep their initial value; a missing
            /// `Points` array, a wrong length or a value out of range is an error.
            pub fn from_columns(arrays: &[(String, Vec<f64>)]) -> Result<Self, String> {
                let pts = arrays
                    .iter()
                    .find(|a| a.0 == "Points")
                    .ok_or("no Points array")?;
                let n = pts.1.len() / 3;
                let mut p = Particles::<D>::default();
                for k in 0..n {
                    p.push(NewParticle {
                        position: Vector::zero(),
                        velocity: Vector::zero(),
                        kind: Kind::Fluid,
                        phase: 0,
                        density: 0.0,
                    });
                    p.id[k] = k as u32;
                }
                $( read_column(&mut p.$name, $vtu, arrays)?; )*
                Ok(p)
            }
        }
    };
}

/// How a field's value travels between processes: as `WIDTH` numbers.
pub trait Packed: Sized + Copy {
    /// Numbers per value.
    const WIDTH: usize;
    /// Appends the value's numbers.
    fn pack(&self, out: &mut Vec<f64>);
    /// The value from its numbers; `None` when out of range.
    fn unpack(v: &[f64]) -> Option<Self>;
}

impl<const D: usize> Packed for Vector<D> {
    const WIDTH: usize = D;
    fn pack(&self, out: &mut Vec<f64>) {
        out.extend_from_slice(&self.0);
    }
    fn unpack(v: &[f64]) -> Option<Self> {
        Vector::from_slice(v)
    }
}

/// Numbers and integers travel as their one number (exact in an `f64` up to 2^53).
macro_rules! packed_number {
    ($($t:ty),*) => {$(
        impl Packed for $t {
            const WIDTH: usize = 1;
            fn pack(&self, out: &mut Vec<f64>) {
                out.push(*self as f64);
            }
            fn unpack(v: &[f64]) -> Option<Self> {
                let x = *v.first()?;
                let back = x as $t;
                (back as f64 == x).then_some(back)
            }
        }
    )*};
}
packed_number!(u16, u32);

impl Packed for f64 {
    const WIDTH: usize = 1;
    fn pack(&self, out: &mut Vec<f64>) {
        out.push(*self);
    }
    fn unpack(v: &[f64]) -> Option<Self> {
        v.first().copied()
    }
}

impl Packed for Kind {
    const WIDTH: usize = 1;
    fn pack(&self, out: &mut Vec<f64>) {
        out.push(*self as u8 as f64);
    }
    fn unpack(v: &[f64]) -> Option<Self> {
        <Kind as ColumnValue>::from_components(v)
    }
}

impl Packed for bool {
    const WIDTH: usize = 1;
    fn pack(&self, out: &mut Vec<f64>) {
        out.push(*self as u8 as f64);
    }
    fn unpack(v: &[f64]) -> Option<Self> {
        <bool as ColumnValue>::from_components(v)
    }
}

/// The id of the particle at index `v` ([`NONE`] stays).
fn id_at(id: &[u32], v: u32) -> u32 {
    if v == NONE {
        NONE
    } else {
        id[v as usize]
    }
}

/// Replaces each particle index `v` (not [`NONE`]) by `inverse[v]`.
fn remap_indices(v: &mut [u32], inverse: &[u32]) {
    for x in v {
        if *x != NONE {
            *x = inverse[*x as usize];
        }
    }
}

fn column<T: ColumnValue>(values: &[T], vtu: Vtu) -> Option<Column> {
    let name = match vtu {
        Vtu::Points => "Points",
        Vtu::Data(name) => name,
        Vtu::Internal => return None,
    };
    let mut bytes = Vec::with_capacity(values.len() * T::COMPONENTS * 8);
    for v in values {
        v.put(&mut bytes);
    }
    Some(Column {
        name,
        vtk_type: T::VTK_TYPE,
        components: T::COMPONENTS,
        bytes,
    })
}

fn read_column<T: ColumnValue>(
    out: &mut [T],
    vtu: Vtu,
    arrays: &[(String, Vec<f64>)],
) -> Result<(), String> {
    let name = match vtu {
        Vtu::Points => "Points",
        Vtu::Data(name) => name,
        Vtu::Internal => return Ok(()),
    };
    let Some((_, values)) = arrays.iter().find(|a| a.0 == name) else {
        return Ok(());
    };
    if values.len() != out.len() * T::COMPONENTS {
        return Err(format!(
            "array `{name}` has {} values, expected {} x {}",
            values.len(),
            out.len(),
            T::COMPONENTS
        ));
    }
    for (k, c) in values.chunks_exact(T::COMPONENTS).enumerate() {
        out[k] = T::from_components(c)
            .ok_or_else(|| format!("array `{name}`: value {c:?} of particle {k} out of range"))?;
    }
    Ok(())
}

particle_fields! { |new, index|
    /// Stable particle id, kept through reordering.
    id: u32 = index => Vtu::Data("id");
    /// Position (m).
    position: Vector<D> = new.position => Vtu::Points;
    /// Velocity (m/s).
    velocity: Vector<D> = new.velocity => Vtu::Data("velocity");
    /// Pressure (Pa).
    pressure: f64 = 0.0 => Vtu::Data("pressure");
    /// Density (kg/m^3); wall and dummy particles take the density of the fluid beside them.
    density: f64 = new.density => Vtu::Data("density");
    /// Phase index into the case's phase table.
    phase: u16 = new.phase => Vtu::Data("phase");
    /// Fluid (0), wall (1) or dummy (2).
    kind: Kind = new.kind => Vtu::Data("kind");
    /// Free-surface flag (Dirichlet `p = 0` in the PPE).
    free_surface: bool = false => Vtu::Data("free_surface");
    /// Particle number density at `re_grad` (dimensionless).
    number_density: f64 = 0.0 => Vtu::Data("number_density");
    /// For dummy particles: index of the wall particle that backs it (pressure extrapolation).
    backing_wall: u32 = NONE => Vtu::Internal, particle_index;
    /// Fluid group for diagnostics (`NO_GROUP` when the region has none).
    group: u16 = NO_GROUP => Vtu::Internal;
}

impl<const D: usize> Particles<D> {
    /// Where a row of [`Self::pack`] holds the id (the first field).
    pub const PACKED_ID: usize = 0;
    /// Where a row of [`Self::pack`] holds the position's `D` numbers (the second field).
    pub const PACKED_POSITION: usize = 1;

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.position.len()
    }
    /// True when there are no particles.
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }
    /// Number of particles of a kind.
    pub fn count(&self, kind: Kind) -> usize {
        self.kind.iter().filter(|&&k| k == kind).count()
    }

    /// The particles `0 .. n` alone (an index to a particle beyond `n` becomes [`NONE`]).
    pub fn first(&self, n: usize) -> Particles<D> {
        Particles::joined(std::iter::once((self, n)))
    }

    /// The particles `0 .. n` of each part, one after the other, in id order, their index
    /// fields pointing within the whole.
    pub fn joined<'a>(parts: impl Iterator<Item = (&'a Particles<D>, usize)>) -> Particles<D> {
        let mut out = Particles::default();
        let mut row = Vec::with_capacity(Self::packed_width());
        for (p, n) in parts {
            for i in 0..n.min(p.len()) {
                row.clear();
                p.pack(i, &mut row);
                out.push_packed(&row).expect("a row packed here reads back");
            }
        }
        out.ids_to_indices();
        let mut order: Vec<u32> = (0..out.len() as u32).collect();
        order.sort_unstable_by_key(|&k| out.id[k as usize]);
        out.permute(&order);
        out
    }
}

// Spare arrays of the particle fields' element types: a step gives back the arrays it is
// done with and takes them again for its next results, so a warm step allocates nothing
// (issue 15; docs/decisions.md, "A step without allocations").

/// Spare arrays by element type.
#[derive(Debug, Default)]
pub struct SpareArrays<const D: usize> {
    vectors: Vec<Vec<Vector<D>>>,
    scalars: Vec<Vec<f64>>,
    flags: Vec<Vec<bool>>,
    indices: Vec<Vec<u32>>,
    shorts: Vec<Vec<u16>>,
    kinds: Vec<Vec<Kind>>,
}

/// An element type [`SpareArrays`] keeps (every particle field's).
pub trait Spared<const D: usize>: Sized {
    /// The spare arrays of this type.
    fn list(spare: &mut SpareArrays<D>) -> &mut Vec<Vec<Self>>;
}

macro_rules! spared {
    ($($ty:ty => $list:ident),* $(,)?) => {$(
        impl<const D: usize> Spared<D> for $ty {
            fn list(spare: &mut SpareArrays<D>) -> &mut Vec<Vec<Self>> {
                &mut spare.$list
            }
        }
    )*};
}

spared!(Vector<D> => vectors, f64 => scalars, bool => flags, u32 => indices, u16 => shorts, Kind => kinds);

impl<const D: usize> SpareArrays<D> {
    /// A spare array (empty, with the capacity it had), or a new one.
    pub fn take<T: Spared<D>>(&mut self) -> Vec<T> {
        let mut v = T::list(self).pop().unwrap_or_default();
        v.clear();
        v
    }

    /// Keeps `v`'s memory for a later [`SpareArrays::take`].
    pub fn give<T: Spared<D>>(&mut self, v: Vec<T>) {
        if v.capacity() > 0 {
            T::list(self).push(v);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An array given back is handed out again, emptied, with its memory; a type with no
    /// spare array gets a new one.
    #[test]
    fn a_given_array_is_taken_again_empty_with_its_memory() {
        let mut spare = SpareArrays::<2>::default();
        let v = vec![1.0f64; 1000];
        let at = v.as_ptr();
        spare.give(v);
        let w: Vec<f64> = spare.take();
        assert!(w.is_empty() && w.capacity() >= 1000 && w.as_ptr() == at);
        let flags: Vec<bool> = spare.take();
        assert_eq!(flags.capacity(), 0);
    }

    fn two() -> Particles<2> {
        let mut p = Particles::<2>::default();
        for (k, kind) in [Kind::Fluid, Kind::Wall, Kind::Dummy]
            .into_iter()
            .enumerate()
        {
            p.push(NewParticle {
                position: Vector([k as f64, 0.5]),
                velocity: Vector([1.0, -1.0]),
                kind,
                phase: 0,
                density: 1000.0,
            });
        }
        p.backing_wall[2] = 1;
        p
    }

    #[test]
    fn permute_moves_every_field_and_remaps_indices() {
        let mut p = two();
        p.permute(&[2, 0, 1]);
        assert_eq!(p.id, vec![2, 0, 1]);
        assert_eq!(p.kind, vec![Kind::Dummy, Kind::Fluid, Kind::Wall]);
        // The dummy (now first) is backed by the wall, now at index 2.
        assert_eq!(p.backing_wall[0], 2);
        assert_eq!(p.inconsistent_field(), None);
    }

    #[test]
    fn retain_removes_from_every_field_and_remaps_indices() {
        let mut p = two();
        // Remove the fluid particle (index 0): the dummy's backing wall moves from 1 to 0.
        assert_eq!(p.retain(&[false, true, true]), 1);
        assert_eq!(p.id, vec![1, 2]);
        assert_eq!(p.kind, vec![Kind::Wall, Kind::Dummy]);
        assert_eq!(p.backing_wall, vec![NONE, 0]);
        assert_eq!(p.inconsistent_field(), None);
        // Removing the wall leaves the dummy without one.
        assert_eq!(p.retain(&[false, true]), 1);
        assert_eq!(p.backing_wall, vec![NONE]);
        assert_eq!(p.retain(&[true]), 0);
    }

    #[test]
    fn packed_particles_come_back_with_ids_in_index_fields() {
        let p = two();
        let mut row = Vec::new();
        // The dummy and its backing wall, in the other order.
        let mut q = Particles::<2>::default();
        for i in [2, 1] {
            row.clear();
            p.pack(i, &mut row);
            assert_eq!(row.len(), Particles::<2>::packed_width());
            assert_eq!(row[Particles::<2>::PACKED_ID], p.id[i] as f64);
            let at = Particles::<2>::PACKED_POSITION;
            assert_eq!(row[at..at + 2], p.position[i].0);
            q.push_packed(&row).unwrap();
        }
        assert_eq!(
            q.backing_wall,
            vec![1, NONE],
            "the wall's id before the remap"
        );
        q.ids_to_indices();
        assert_eq!(q.backing_wall, vec![1, NONE]);
        assert_eq!(q.id, vec![2, 1]);
        assert_eq!(q.kind, vec![Kind::Dummy, Kind::Wall]);
        assert_eq!(q.position, vec![p.position[2], p.position[1]]);
        assert_eq!(q.inconsistent_field(), None);
        // Without its wall the dummy has none; a short row is refused.
        let mut r = Particles::<2>::default();
        row.clear();
        p.pack(2, &mut row);
        r.push_packed(&row).unwrap();
        r.ids_to_indices();
        assert_eq!(r.backing_wall, vec![NONE]);
        assert!(r.push_packed(&row[..3]).is_none());
    }

    #[test]
    fn columns_read_back_into_the_same_fields() {
        let mut p = two();
        p.pressure = vec![12.5, -3.0, 0.0];
        p.free_surface[0] = true;
        let arrays: Vec<(String, Vec<f64>)> = p
            .columns()
            .iter()
            .map(|c| {
                let vals = match c.vtk_type {
                    "Float64" => c
                        .bytes
                        .chunks(8)
                        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
                        .collect(),
                    "Int32" => c
                        .bytes
                        .chunks(4)
                        .map(|b| i32::from_le_bytes(b.try_into().unwrap()) as f64)
                        .collect(),
                    _ => c.bytes.iter().map(|&b| b as f64).collect(),
                };
                (c.name.to_string(), vals)
            })
            .collect();
        let q = Particles::<2>::from_columns(&arrays).unwrap();
        assert_eq!(q.position, p.position);
        assert_eq!(q.velocity, p.velocity);
        assert_eq!(q.pressure, p.pressure);
        assert_eq!(q.kind, p.kind);
        assert_eq!(q.free_surface, p.free_surface);
        // Internal fields are not written: they come back at their initial value.
        assert_eq!(q.backing_wall, vec![NONE; 3]);
    }

    #[test]
    fn a_short_array_is_an_error() {
        let arrays = vec![
            ("Points".to_string(), vec![0.0; 6]),
            ("pressure".to_string(), vec![1.0]),
        ];
        let e = Particles::<2>::from_columns(&arrays).unwrap_err();
        assert!(e.contains("pressure"), "{e}");
    }
}
