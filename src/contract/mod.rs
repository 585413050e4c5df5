//! What the contract (`docs/api.md`) fixes in code shared by every layer: the names of the
//! domain's enums in the API, the webhooks and the database ([`names`], the `contract_names!`
//! tables), and the integers of JSON bodies as JSON Schema counts them ([`json_integer`]).

pub mod json_integer;
pub mod names;
