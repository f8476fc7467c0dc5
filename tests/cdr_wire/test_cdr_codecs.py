"""The compiled CDR codecs of cdr_wire.cdr_codecs against mcap_ros2's writer and reader."""

import dataclasses
import io

from cdr_translator.interface import messages
from cdr_translator.interface.settings import TranslatorSettings
from cdr_translator.interface.wrench_processing import WrenchProcessor
from cdr_wire.cdr_codecs import decoder, encoder, ShippedDecoders
from cdr_wire.msgdefs import MESSAGE_DEFINITIONS, shipped_types
from cdr_wire.reader import Decoders, McapSource
from mcap.reader import make_reader
from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory
from mcap_ros2.writer import Writer as Ros2Writer
from msg_tools import synth
import numpy as np
import pytest

STAMP = {'sec': 1_700_000_000, 'nanosec': 123_456_789}


def _plain(value):
    """Return a message mcap_ros2 decoded as nested dicts and lists."""
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    if hasattr(value, '__slots__'):
        return {name: _plain(getattr(value, name)) for name in value.__slots__}
    return value


def _written_by_mcap_ros2(type_name, message):
    """Return the CDR bytes mcap_ros2's MCAP writer stores for a message given as a dict."""
    stream = io.BytesIO()
    writer = Ros2Writer(stream)
    schema = writer.register_msgdef(type_name, MESSAGE_DEFINITIONS[type_name])
    writer.write_message('/reference', schema, message, log_time=0)
    writer.finish()
    stream.seek(0)
    ((_, _, record),) = make_reader(stream).iter_messages()
    return record.data


@pytest.fixture(scope='module')
def outputs():
    """Every message the node publishes: a solve with compliance and backbones, a rejection."""
    settings = TranslatorSettings.from_params_file(None)
    processor = WrenchProcessor(settings.params, settings, compliance=True, backbones=True)
    solved = processor.process(np.array([12.0, -3.5, 1.0]), np.array([0.0, 0.02, 0.0]),
                               '', STAMP)
    rejected = processor.process(np.array([np.nan, 0.0, 0.0]), np.zeros(3), '', STAMP)
    wrench = messages.wrench_message([1.5, -2.0, 0.25], [0.0, 0.1, -0.2], 'base', STAMP)
    return solved.outputs + rejected.outputs + [('wrench', messages.WRENCH_TYPE, wrench)]


def test_output_bytes_equal_mcap_ros2s(outputs):
    """Each output message encodes to exactly the bytes mcap_ros2 writes."""
    assert {type_name for _, type_name, _ in outputs} == set(messages.TOPIC_TYPES.values())
    for _, type_name, message in outputs:
        assert encoder(type_name)(message) == _written_by_mcap_ros2(type_name, message), type_name


def test_decoded_messages_equal_mcap_ros2s(outputs):
    """Read back, the bytes give the message mcap_ros2 reads (as dicts), and encode again."""
    factory = DecoderFactory()   # it keeps a decoder per schema id
    for schema_id, (_, type_name, message) in enumerate(outputs, 1):
        data = encoder(type_name)(message)
        schema = Schema(id=schema_id, name=type_name, encoding='ros2msg',
                        data=MESSAGE_DEFINITIONS[type_name].encode())
        reference = _plain(factory.decoder_for('cdr', schema)(data))
        decoded = decoder(type_name)(data)
        assert decoded == reference, type_name
        assert encoder(type_name)(decoded) == data


def test_every_shipped_type_has_codecs():
    """Each shipped type's layout is read from its description; its zero message round-trips."""
    for type_name in shipped_types():
        empty = decoder(type_name)(encoder(type_name)({}))
        assert encoder(type_name)(empty) == _written_by_mcap_ros2(type_name, empty), type_name


def test_truncated_bytes_raise_value_error():
    """A message cut short is a ValueError, not a wrong message."""
    data = encoder(messages.POSE_TYPE)(messages.pose_message(_Pose(), STAMP, 'base'))
    with pytest.raises(ValueError):
        decoder(messages.POSE_TYPE)(data[:-8])


class _Pose:
    """The pose fields of a result."""

    end_disk_position = np.array([0.001, -0.002, 0.1])
    end_disk_quaternion_xyzw = np.array([0.0, 0.0, 0.0, 1.0])


def test_shipped_decoders_read_as_the_files_own(tmp_path):
    """The shipped decoders give the wrenches the file's decoder gives; damage fails alike."""
    bag = tmp_path / 'ramp.mcap'
    synth.write_wrenches(bag, synth.generate('ramp', count=5, force=(3.0, -1.0, 2.0)))
    fast, reference = ShippedDecoders(), Decoders()
    for raw in McapSource(bag).messages():
        assert isinstance(fast.decode(raw), dict)   # the compiled reader's
        assert (str(messages.wrench_from_message(fast.decode(raw)))
                == str(messages.wrench_from_message(reference.decode(raw))))
        cut = dataclasses.replace(raw, data=raw.data[:20])
        with pytest.raises(ValueError) as fast_error:
            fast.decode(cut)
        with pytest.raises(ValueError) as reference_error:
            reference.decode(cut)
        assert str(fast_error.value) == str(reference_error.value)


@pytest.mark.parametrize('message', [
    {},
    {'header': {'stamp': STAMP, 'frame_id': 'ba'}, 'status': []},
    {'header': {'frame_id': 'é'}, 'status': [
        {'level': b'\x02', 'name': 'n', 'message': 'three', 'hardware_id': '',
         'values': [{'key': 'k', 'value': ''}, {'key': '', 'value': 'vé'}]},
        {'level': 1, 'values': [{'key': 'kk'}]},
        {'name': 'only a name'}]},
])
def test_diagnostic_array_bytes_equal_mcap_ros2s(message):
    """The hand-laid DiagnosticArray writer: odd lengths, UTF-8, byte levels, missing fields."""
    type_name = messages.DIAGNOSTIC_ARRAY_TYPE
    filled = decoder(type_name)(encoder(type_name)(message))
    assert encoder(type_name)(message) == _written_by_mcap_ros2(type_name, filled)
    assert encoder(type_name)(filled) == encoder(type_name)(message)
