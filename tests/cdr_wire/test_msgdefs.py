"""The shipped message definitions: complete texts, REP-2011 field types, bad type names."""

from cdr_wire import msgdefs
import pytest

OUTPUT_TYPES = ('geometry_msgs/msg/WrenchStamped', 'geometry_msgs/msg/PoseStamped',
                'sensor_msgs/msg/JointState', 'std_msgs/msg/Float64MultiArray',
                'visualization_msgs/msg/MarkerArray', 'diagnostic_msgs/msg/DiagnosticArray')


def test_every_output_type_is_shipped():
    """The six types the node and replay use have complete definitions."""
    for type_name in OUTPUT_TYPES:
        assert type_name in msgdefs.MESSAGE_DEFINITIONS


def test_field_types_follow_the_field_type_ids():
    """Arrays, bounded sequences and bounded strings get REP-2011 ids and capacities."""
    fixed = msgdefs._parse_field('float64[36] covariance', 'geometry_msgs')
    assert (fixed.type_id, fixed.capacity) == (59, 36)   # FIELD_TYPE_DOUBLE_ARRAY
    bounded = msgdefs._parse_field('string<=5[<=3] names  # comment', 'pkg')
    assert (bounded.type_id, bounded.capacity, bounded.string_capacity) == (117, 3, 5)
    nested = msgdefs._parse_field('Point[] points', 'geometry_msgs')
    assert (nested.type_id, nested.nested_type_name, nested.dependency) == (
        145, 'geometry_msgs/msg/Point', 'geometry_msgs/Point')
    assert msgdefs._strip_comment('string a "x#y" # tail') == 'string a "x#y" '


@pytest.mark.parametrize('bad', ['geometry_msgs/WrenchStamped', 'WrenchStamped', 'a/msg/',
                                 'nope_msgs/msg/Nothing', None])
def test_bad_type_names_are_value_errors(bad):
    """Unknown or malformed type names raise ValueError naming them."""
    with pytest.raises(ValueError, match='message'):
        msgdefs.type_hash(bad)
