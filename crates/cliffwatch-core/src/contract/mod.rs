//! What the contract (`docs/api.md`) fixes in code shared by every layer: the names of the
//! domain's enums in the API, the webhooks and the database ([`names`], the `contract_names!`
//! tables), the integers of JSON bodies as JSON Schema counts them ([`json_integer`]), and how
//! much of a user's value an error message repeats ([`echo`]).

pub mod echo;
pub mod json_integer;
pub mod names;

pub use echo::truncate_for_message;
