//! By-name SDO access: a name from the node's device description resolves to the entry's
//! address and data type, which then check the Rust type asked for.

use super::error::NetError;
use super::sdo::RemoteSdo;
use super::value::AnyValue;
use crate::frame::cob_id::NodeId;
use crate::od::{DataType, OdValue};

/// What a name resolved to.
pub(super) struct Resolved {
    pub node: NodeId,
    pub index: u16,
    pub sub: u8,
    pub data_type: DataType,
}

/// True when a value of Rust type `asked` reads and writes an entry of type `have`: same
/// size, same signedness and realness (so BOOLEAN and UNSIGNED8 share `u8`, and TIME types
/// have none).
fn fits(have: DataType, asked: DataType) -> bool {
    have == asked
        || (have.fixed_size().is_some()
            && have.fixed_size() == asked.fixed_size()
            && have.is_signed() == asked.is_signed()
            && have.is_real() == asked.is_real()
            && !matches!(have, DataType::TimeOfDay | DataType::TimeDifference))
}

impl RemoteSdo {
    /// The entry `name` names in the node's description (the rules of
    /// [`Description::entry`](crate::eds::Description::entry): `"Producer heartbeat time"`,
    /// `"0x1017"`, `"1018sub1"`, `"Identity object.Vendor-ID"`, without regard to case).
    pub(super) fn resolve(&self, name: &str) -> Result<Resolved, NetError> {
        let node = self.remote().id()?;
        let desc = self
            .remote()
            .description()
            .ok_or(NetError::NoDescription { node })?;
        let e = desc
            .entry(name)
            .map_err(|error| NetError::Name { node, error })?;
        Ok(Resolved {
            node,
            index: e.index,
            sub: e.sub,
            data_type: e.data_type,
        })
    }

    fn typed<T: OdValue>(&self, name: &str) -> Result<Resolved, NetError> {
        let r = self.resolve(name)?;
        if !fits(r.data_type, T::TYPE) {
            return Err(NetError::WrongType {
                node: r.node,
                name: name.into(),
                index: r.index,
                sub: r.sub,
                data_type: r.data_type,
                asked: T::TYPE,
            });
        }
        Ok(r)
    }

    /// Reads the entry `name` names in the node's device description as a `T`, which must
    /// match the entry's data type (`u16` for UNSIGNED16, …): otherwise
    /// [`NetError::WrongType`], before anything is sent. An unknown or ambiguous name is
    /// [`NetError::Name`], a node without a description [`NetError::NoDescription`].
    pub async fn read_named<T: OdValue>(&self, name: &str) -> Result<T, NetError> {
        let r = self.typed::<T>(name)?;
        self.read(r.index, r.sub).await
    }

    /// Writes `value` to the entry `name` names, checked as [`RemoteSdo::read_named`] checks.
    pub async fn write_named<T: OdValue>(&self, name: &str, value: T) -> Result<(), NetError> {
        let r = self.typed::<T>(name)?;
        self.write(r.index, r.sub, value).await
    }

    /// Reads the entry `name` names, typed by its data type in the description: numbers of
    /// any width, text, bytes.
    pub async fn read_value(&self, name: &str) -> Result<AnyValue, NetError> {
        let r = self.resolve(name)?;
        let data = self.read_bytes(r.index, r.sub).await?;
        AnyValue::decode(r.data_type, &data).ok_or(NetError::WrongSize {
            node: r.node,
            index: r.index,
            sub: r.sub,
            expected: r.data_type.fixed_size().unwrap_or(0),
            got: data.len(),
        })
    }

    /// Writes `value` (`5u16.into()`, `"text".into()`, an [`AnyValue`]) to the entry `name`
    /// names, encoded as its data type says; a value outside the type is
    /// [`NetError::BadValue`], before anything is sent.
    pub async fn write_value(
        &self,
        name: &str,
        value: impl Into<AnyValue>,
    ) -> Result<(), NetError> {
        let r = self.resolve(name)?;
        let bytes = value
            .into()
            .encode(r.data_type)
            .map_err(|why| NetError::BadValue {
                node: r.node,
                object: format!("{name:?} ({:#06x} sub {})", r.index, r.sub),
                why,
            })?;
        self.write_bytes(r.index, r.sub, bytes).await
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rust_types_fit_their_data_types_only() {
        assert!(fits(DataType::Unsigned16, u16::TYPE));
        assert!(fits(DataType::Boolean, u8::TYPE));
        assert!(!fits(DataType::Unsigned16, u32::TYPE));
        assert!(!fits(DataType::Unsigned16, i16::TYPE));
        assert!(!fits(DataType::Unsigned24, u32::TYPE));
        assert!(!fits(DataType::Real32, u32::TYPE));
        assert!(!fits(DataType::VisibleString, u8::TYPE));
    }
}
