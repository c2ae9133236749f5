"""bev_mdo's messages: their types and CDR codec, generated from the .msg files, batches of named
columns in and out of them, and their signatures. No ROS import: the nodes (``bev_mdo.ros``), the
recorder and the bag readers (``bev_mdo.bag``) all use this one codec.

- ``messages``: the generated types (EvaluationRequest, EvaluationResult, NamedArray, ...), ``encode``,
  ``decode``, ``new``;
- ``batches``: {name: column} <-> NamedArray, point errors and partials in a result;
- ``signing``: HMAC-SHA256 signatures over the bytes that are sent.
"""
from bev_mdo.protocol.batches import (MAX_BATCH, MAX_NAMES, MAX_REASON_LEN, batch, decode_request, decode_result,
                                      encode_request, encode_result, fill_iteration_record, from_named_array,
                                      parse_start_tag, partials_batch, partials_of, point_errors_of, put_point_errors,
                                      request, result, to_named_array)
from bev_mdo.protocol.messages import (DisciplineInfo, EvaluationRequest, EvaluationResult, Header, IterationRecord,
                                       NamedArray, ParetoFront, WireError, decode, encode, head, new, to_protocol)

__all__ = [
    "MAX_BATCH", "MAX_NAMES", "MAX_REASON_LEN", "batch", "decode_request", "decode_result", "encode_request",
    "encode_result", "fill_iteration_record", "from_named_array", "parse_start_tag", "partials_batch", "partials_of",
    "point_errors_of", "put_point_errors", "request", "result", "to_named_array",
    "DisciplineInfo", "EvaluationRequest", "EvaluationResult", "Header", "IterationRecord", "NamedArray",
    "ParetoFront", "WireError", "decode", "encode", "head", "new", "to_protocol",
]
