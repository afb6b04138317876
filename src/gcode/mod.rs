//! RS-274 / ISO 6983 G-code: lossless nom parser, block model, emitter.
