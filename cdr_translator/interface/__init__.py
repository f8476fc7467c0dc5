"""
ROS-free node contracts: what each node does with one input and the messages it publishes.

Both nodes (cdr_translator.ros) and the offline replay (msg_tools.replay) use these, so a
recording replayed offline gives exactly what the live node published.
"""
