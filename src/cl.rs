//! APT CL data (GOTO/...) reader.
