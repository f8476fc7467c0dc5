"""
The wire format of cdr_translator's messages: CDR codecs, MCAP files, rosbag2 metadata.

What the ROS 2 nodes (``cdr_translator.ros``) and the offline tools (``msg_tools``) both put
on disk and read back, with no ROS installed and no solver: it imports nothing from
``cdr_translator`` and nothing from rclpy or the ROS message packages, and both of them
import it (wire <- ros nodes, msg_tools apps). It is a top-level package beside the two,
not a part of either, so that neither edge depends on the other one's package to reach it,
and so that its independence is visible from the folder names: inside ``msg_tools`` it
would sit among the apps that import the solver, inside ``cdr_translator`` among the
layers it must not use. The mcap library is cut the same way (a ROS-free core, ROS 2
support an add-on): here ``cdr_translator.ros.serialization`` is the add-on that reads a
plan from rclpy's generated classes.

Modules:

* ``cdr_plan``: CDR writers and readers compiled from a message type's field layout;
* ``msgdefs`` and ``msg/``: the shipped .msg texts, rosbag2's definition text, REP-2011
  type descriptions and hashes;
* ``cdr_codecs``: the shipped types' encoders and decoders by type name;
* ``mcap_log``: ``McapLog``, the thread-safe, crash-tolerant ROS 2 MCAP writer;
* ``log_process``: an ``McapLog`` in a child process (the nodes' log);
* ``reader``: ``McapSource``, the reader that salvages damaged files; ``mcap_framing``
  its checks of a file's summary and chunk index;
* ``rosbag2_metadata``, ``file_lock``, ``log_status``, ``errors``: rosbag2's QoS and distro
  records, one writer per file, what a writer reports, and the errors of a log file.
"""
