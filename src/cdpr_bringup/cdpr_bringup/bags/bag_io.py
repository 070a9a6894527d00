"""Bags of the graph: writing them so that a killed recorder leaves a readable prefix,
and reading them back (timed messages per topic, the Recording per control tick).

A bag is a rosbag2 folder (metadata.yaml and one MCAP or sqlite3 file) with the message
definitions and type hashes of the ROS 2 Kilted types embedded, so `ros2 bag info`,
rosbags, and MCAP viewers open it without the message packages.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import yaml
from mcap.exceptions import EndOfFile
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType
from mcap.writer import Writer as McapFileWriter
from rosbags.interfaces import MessageDefinitionFormat
from rosbags.rosbag2 import CompressionMode, Reader, StoragePlugin, Writer
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer
from rosbags.typesys import Stores, get_typestore

from cdpr_fdi.view.markers import FRAME_ID, Frame, Shape
from cdpr_msgs_py import contract
from cdpr_msgs_py.stamps import NANOSECONDS, ns_parts, stamp_to_ns

from cdpr_msgs_py import cdr as bulk_cdr
from ..runs.recording import Recording
from ..runs.metrics import STATES_TOTAL_KEY

# A chunk is what survives a SIGKILL whole, so chunks stay small; the recorder also
# flushes the open one on a timer when traffic is too slow to fill it.
CHUNK_SIZE_BYTES = 64 * 1024
TYPESTORE = get_typestore(Stores.ROS2_KILTED)


class _McapStorage:
    """rosbags' storage-writer protocol on the mcap package's Writer.

    rosbags' own MCAP storage closes a chunk only past 1 MiB and cannot be flushed; this
    one writes what rosbag2's MCAP plugin writes (ros2 profile, ros2msg schemas, QoS and
    type hash per channel, the bag metadata as a `rosbag2` metadata record) in chunks of
    CHUNK_SIZE_BYTES, and `flush` closes the open chunk and pushes it to the OS.
    """

    def __init__(self, path: Path, compression: CompressionMode):
        self.path = path / f'{path.name}.mcap'
        self.stream = self.path.open('xb')
        self.writer = McapFileWriter(
            self.stream, chunk_size=CHUNK_SIZE_BYTES,
            compression=CompressionType.ZSTD if compression == CompressionMode.STORAGE
            else CompressionType.NONE)
        self.writer.start(profile='ros2', library='cdpr_bringup bag_io')
        self.schema_ids: dict[str, int] = {}
        self.channel_ids: dict[int, int] = {}

    def add_msgtype(self, connection) -> None:
        encoding = 'ros2msg' if connection.msgdef.format == MessageDefinitionFormat.MSG else 'ros2idl'
        self.schema_ids[connection.msgtype] = self.writer.register_schema(
            connection.msgtype, encoding, connection.msgdef.data.encode())

    def add_connection(self, connection, offered_qos_profiles: str) -> None:
        self.channel_ids[connection.id] = self.writer.register_channel(
            connection.topic, connection.ext.serialization_format,
            self.schema_ids[connection.msgtype],
            {'offered_qos_profiles': offered_qos_profiles, 'topic_type_hash': connection.digest})

    def write(self, connection, timestamp: int, data: bytes) -> None:
        self.writer.add_message(self.channel_ids[connection.id], timestamp, bytes(data), timestamp)

    def flush(self) -> None:
        self.writer.flush()

    def close(self, _version: int, metadata: str) -> None:
        self.writer.add_metadata('rosbag2', {'serialized_metadata': metadata})
        self.writer.finish()
        self.stream.close()

    def abort(self) -> None:
        self.stream.close()


class _Sqlite3Storage(Sqlite3Writer):
    """rosbags' sqlite3 storage, committed on `flush` so a killed writer keeps its rows."""

    def flush(self) -> None:
        self.conn.commit()


class BagWriter(Writer):
    """rosbags' rosbag2 Writer whose storage can be flushed while it records."""

    STORAGE_PLUGINS = {StoragePlugin.MCAP: _McapStorage, StoragePlugin.SQLITE3: _Sqlite3Storage}

    def __init__(self, path: str | Path, storage: str = 'mcap'):
        plugins = {plugin.name.lower(): plugin for plugin in self.STORAGE_PLUGINS}
        if storage not in plugins:
            raise ValueError(f'storage must be one of {", ".join(plugins)}, got {storage!r}')
        super().__init__(Path(path), version=9, storage_plugin=plugins[storage])

    def open(self) -> None:
        # a bag inside folders that do not exist yet (the demo launch's runs/demo_launch/<time>/bag)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        super().open()

    def add_topic(self, topic: str, msgtype: str, offered_qos_profiles=()):
        """A connection with the Kilted definition and hash of `msgtype` embedded."""
        return self.add_connection(topic, msgtype, typestore=TYPESTORE,
                                   offered_qos_profiles=offered_qos_profiles)

    def flush(self) -> None:
        """Make everything written so far survive a kill of this process."""
        self.storage.flush()


# The recorder's count of the ticks each per-tick topic lacks (JSON, topic → ticks), in
# the bag's metadata (rosbag2 custom_data).
MISSING_TICKS_KEY = 'cdpr.missing_ticks'


def missing_ticks(bag: str | Path) -> dict[str, int] | None:
    """Per per-tick topic, the ticks its recorder counted missing (tick_gaps); None for a
    bag whose recorder did not count (killed before it closed the bag, or written in
    process, where nothing is lost)."""
    metadata = Path(bag) / 'metadata.yaml'
    if not metadata.exists():
        return None
    information = yaml.safe_load(metadata.read_text()).get('rosbag2_bagfile_information', {})
    value = (information.get('custom_data') or {}).get(MISSING_TICKS_KEY)
    return None if value is None else json.loads(value)


def is_complete(bag: str | Path) -> bool:
    """False for the folder of a recorder that was killed: it never wrote metadata.yaml."""
    bag = Path(bag)
    return not bag.is_dir() or (bag / 'metadata.yaml').exists()


def mcap_prefix(path: str | Path):
    """(topic, msgtype, log time ns, CDR data) of every message in the complete chunks of
    an MCAP file, also one whose writer died mid-chunk (read with the mcap package only)."""
    with open(path, 'rb') as file:
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        try:
            for record in StreamReader(_ExactReads(file), validate_crcs=True).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Message):
                    channel = channels[record.channel_id]
                    yield (channel.topic, schemas[channel.schema_id].name, record.log_time,
                           record.data)
        except EndOfFile:
            return


class _ExactReads:
    """A file on which a short read raises EndOfFile: MCAP records are length-prefixed, so
    a record cut by a kill must end the stream rather than be parsed from the bytes left."""

    def __init__(self, file):
        self.file = file

    def read(self, size: int = -1) -> bytes:
        data = self.file.read(size)
        if 0 < size != len(data):
            raise EndOfFile()
        return data


def read_messages(bag: str | Path, topics: list[str]) -> dict[str, list[tuple[int, object]]]:
    """Per topic, (bag time ns, message) in recording order; a killed recorder's MCAP
    bag gives the messages of its complete chunks."""
    found: dict[str, list[tuple[int, object]]] = {topic: [] for topic in topics}
    if is_complete(bag):
        with Reader(bag) as reader:
            connections = [c for c in reader.connections if c.topic in found]
            if connections:
                for connection, timestamp, data in reader.messages(connections=connections):
                    found[connection.topic].append(
                        (timestamp, TYPESTORE.deserialize_cdr(data, connection.msgtype)))
        return found
    files = sorted(Path(bag).glob('*.mcap'))
    if len(files) != 1:
        raise ValueError(f'{bag}: no metadata.yaml and {len(files)} MCAP files; cannot recover')
    for topic, msgtype, timestamp, data in mcap_prefix(files[0]):
        if topic in found:
            found[topic].append((timestamp, TYPESTORE.deserialize_cdr(data, msgtype)))
    return found


def stamp_ns(message) -> int:
    return stamp_to_ns(message.header.stamp)


def read_topics(bag: str | Path, topics: list[str]) -> dict[str, dict[int, object]]:
    """Per topic, the last message of each header stamp (ns); resent ticks count once."""
    return {topic: {stamp_ns(message): message for _, message in messages}
            for topic, messages in read_messages(bag, topics).items()}


# The loop topics a Recording's rows are read from (every tick), and the view topics its
# view rows are (every view tick).
LOOP_TOPICS = (contract.JOINT_STATES, contract.EFFORT_COMMAND, contract.TWIN_JOINT_STATES, contract.REFERENCE)
VIEW_TOPICS = (contract.TWIN_POSE, contract.REFERENCE_POSE)
TRUTH_TOPICS = (contract.GROUND_TRUTH_POSE, contract.GROUND_TRUTH_TENSIONS)


def recording_from_bag(bag: str | Path, namespace: str = '/cdpr', orientations: bool = False) -> Recording:
    """The Recording of a lockstep or realtime run: its loop rows on the ticks that have a
    state, a command, the twin's state and the reference (a killed recorder's last tick
    may lack some), its view rows on the view ticks that have the twin's and the
    reference's pose (and the truth, where there is some).

    Ground truth exists only in simulation: without it the true pose and tensions are NaN;
    the residual is None without the supervisor's /fdi/residual (NaN on ticks it lacks).
    With `orientations` (a platform's bag) the poses' orientations are read too. The
    figures from every tick are the plant's, which metrics.take_statuses adds.
    """
    names = {key: f'{namespace}/{key}' for key in LOOP_TOPICS + VIEW_TOPICS + TRUTH_TOPICS
             + (contract.FDI_RESIDUAL,)}
    found = read_topics(bag, list(names.values()))
    stamps = sorted(set(found[names[contract.JOINT_STATES]]).intersection(
        *(found[names[key]] for key in LOOP_TOPICS)))
    if not stamps:
        raise ValueError(f'{bag}: no tick has all of {", ".join(names[key] for key in LOOP_TOPICS)}')
    # the plant publishes the truth with the view topics, so where there is some it is required
    viewed = list(VIEW_TOPICS) + [key for key in TRUTH_TOPICS if found[names[key]]]
    view_stamps = sorted(set(found[names[viewed[0]]]).intersection(*(found[names[key]] for key in viewed)))
    cables = len(found[names[contract.JOINT_STATES]][stamps[0]].position)

    def joints(key, field, at=stamps):
        messages = found[names[key]]
        return np.array([getattr(messages[s], field) if s in messages else np.full(cables, np.nan)
                         for s in at], dtype=float).reshape(len(at), cables)

    def points(key):
        messages = found[names[key]]
        return np.array([[messages[s].pose.position.x, messages[s].pose.position.y, messages[s].pose.position.z]
                         if s in messages else [np.nan] * 3 for s in view_stamps]).reshape(len(view_stamps), 3)

    def quaternions(key):
        messages = found[names[key]]
        return np.array([[messages[s].pose.orientation.w, messages[s].pose.orientation.x,
                          messages[s].pose.orientation.y, messages[s].pose.orientation.z]
                         if s in messages else [np.nan] * 4 for s in view_stamps]).reshape(len(view_stamps), 4)

    truth = bool(found[names[contract.GROUND_TRUTH_POSE]])
    # a real robot's bag has no ground truth: its orientation is then unknown, not NaN
    turned = ({'twin_orientation': quaternions(contract.TWIN_POSE),
               'reference_orientation': quaternions(contract.REFERENCE_POSE),
               'true_orientation': quaternions(contract.GROUND_TRUTH_POSE) if truth else None}
              if orientations else {})
    return Recording(
        time_s=np.array(stamps) / NANOSECONDS,
        angle_rad=joints(contract.JOINT_STATES, 'position'),
        angular_velocity_rad_s=joints(contract.JOINT_STATES, 'velocity'),
        command_nm=joints(contract.EFFORT_COMMAND, 'effort'),
        twin_angle_rad=joints(contract.TWIN_JOINT_STATES, 'position'),
        twin_angular_velocity_rad_s=joints(contract.TWIN_JOINT_STATES, 'velocity'),
        twin_torque_nm=joints(contract.TWIN_JOINT_STATES, 'effort'),
        reference_angle_rad=joints(contract.REFERENCE, 'position'),
        view_time_s=np.array(view_stamps, dtype=float) / NANOSECONDS,
        twin_position_m=points(contract.TWIN_POSE),
        reference_position_m=points(contract.REFERENCE_POSE),
        true_position_m=points(contract.GROUND_TRUTH_POSE),
        true_tension_n=joints(contract.GROUND_TRUTH_TENSIONS, 'effort', view_stamps),
        residual_nm=(joints(contract.FDI_RESIDUAL, 'effort') if found[names[contract.FDI_RESIDUAL]]
                     else None),
        ticks_held={key: len(found[name]) for key, name in names.items()},
        **turned,
    )


def write_recording(writer: BagWriter, recording: Recording,
                    namespace: str = contract.DEFAULT_NAMESPACE, frame: Frame | None = None) -> None:
    """An in-process Recording into an open bag as the graph would have recorded it, so
    that it gets the same report: the loop topics every tick, the view topics on the view
    ticks, the residual, the verdict and mode changes of the supervisor's summary
    (`recording.fdi`), and that summary on /diagnostics at the last tick. Bag times are the
    tick stamps plus 1 ns per message in the graph's order: the state, the command, the
    reference and the twin, then the supervisor's verdict and mode, then its residual of
    that tick. With a `frame` (cdpr_fdi.view.markers, the markers node's core) also `markers`,
    a frame per view tick after the residual, from the view topics of the same tick, so
    that a viewer shows the run from its bag."""
    types = TYPESTORE.types
    stamps = np.round(recording.time_s * NANOSECONDS).astype(np.int64)
    view_stamps = np.round(recording.view_time_s * NANOSECONDS).astype(np.int64)
    names = contract.joint_names(recording.angle_rad.shape[1])

    def header(stamp):
        sec, nanosec = ns_parts(int(stamp))
        return types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec),
            frame_id='')

    r = recording
    applied = np.vstack([np.zeros_like(r.command_nm[:1]), r.command_nm[:-1]])
    joint_state, pose_stamped = 'sensor_msgs/msg/JointState', 'geometry_msgs/msg/PoseStamped'
    # topic → (type, serialised message of each tick), in the graph's order within a tick
    per_tick = {
        contract.JOINT_STATES: (joint_state, bulk_cdr.joint_states(
            stamps, names, r.angle_rad, r.angular_velocity_rad_s, applied)),
        contract.EFFORT_COMMAND: (joint_state, bulk_cdr.joint_states(stamps, names, effort=r.command_nm)),
        contract.REFERENCE: (joint_state, bulk_cdr.joint_states(stamps, names, r.reference_angle_rad)),
        contract.TWIN_JOINT_STATES: (joint_state, bulk_cdr.joint_states(
            stamps, names, r.twin_angle_rad, r.twin_angular_velocity_rad_s, r.twin_torque_nm)),
    }
    # topic → (type, serialised message of each view tick)
    per_view_tick = {
        contract.TWIN_POSE: (pose_stamped, bulk_cdr.pose_stampeds(view_stamps, r.twin_position_m,
                                                                   r.twin_orientation)),
        contract.REFERENCE_POSE: (pose_stamped, bulk_cdr.pose_stampeds(view_stamps, r.reference_position_m,
                                                                        r.reference_orientation)),
    }
    if r.has_ground_truth:
        per_view_tick[contract.GROUND_TRUTH_POSE] = (pose_stamped, bulk_cdr.pose_stampeds(
            view_stamps, r.true_position_m, r.true_orientation))
        per_view_tick[contract.GROUND_TRUTH_TENSIONS] = (joint_state, bulk_cdr.joint_states(
            view_stamps, names, effort=r.true_tension_n))
    view_row = {int(stamp): row for row, stamp in enumerate(view_stamps)}
    if r.residual_nm is not None:
        residual = bulk_cdr.joint_states(stamps, names, effort=r.residual_nm)
    int32, string = types['std_msgs/msg/Int32'], types['std_msgs/msg/String']
    events: list[tuple[int, str, object]] = []  # (tick, topic, message)
    if r.fdi:
        events += [(0, contract.FDI_BROKEN_CABLE, int32(data=0)),
                   (0, contract.MODE, string(data='NOMINAL'))]
        if r.fdi['identified_tick'] is not None:
            events += [(r.fdi['identified_tick'], contract.FDI_BROKEN_CABLE, int32(data=cable))
                       for cable in r.fdi['broken_cables']]
        events += [(tick, contract.MODE, string(data=mode))
                   for mode, tick in r.fdi['phase_ticks'].items()]
        events.append((stamps.size - 1, contract.DIAGNOSTICS, supervisor_diagnostics(
            r.fdi, header(stamps[-1]), namespace)))
    if r.figures is not None:
        events.append((stamps.size - 1, contract.DIAGNOSTICS, plant_diagnostics(
            r, header(stamps[-1]), namespace)))
    events.sort(key=lambda event: event[0])
    connections = {}

    def write_bytes(topic, msgtype, stamp, data, order_ns):
        if topic not in connections:
            # as ROS resolves names: /diagnostics stays outside the namespace
            name = topic if topic.startswith('/') else f'{namespace}/{topic}'
            connections[topic] = writer.add_topic(name, msgtype)
        writer.write(connections[topic], int(stamp) + order_ns, data)

    def write(topic, stamp, message, order_ns):
        write_bytes(topic, message.__msgtype__, stamp, TYPESTORE.serialize_cdr(message, message.__msgtype__),
                    order_ns)

    for k, stamp in enumerate(stamps):
        order = 0
        for topic, (msgtype, rows) in per_tick.items():
            write_bytes(topic, msgtype, stamp, rows[k].tobytes(), order)
            order += 1
        view = view_row.get(int(stamp))
        if view is not None:
            for topic, (msgtype, rows) in per_view_tick.items():
                write_bytes(topic, msgtype, stamp, rows[view].tobytes(), order)
                order += 1
        while events and events[0][0] == k:
            _, topic, message = events.pop(0)
            write(topic, stamp, message, order)
            order += 1
            if frame is not None and topic == contract.FDI_BROKEN_CABLE:
                frame.on_broken_cable(message.data)
        if r.residual_nm is not None:
            write_bytes(contract.FDI_RESIDUAL, joint_state, stamp, residual[k].tobytes(), order)
            order += 1
        if frame is not None and view is not None:
            frame.on_view('twin', stamp, (r.twin_position_m[view], None if r.twin_orientation is None
                                          else r.twin_orientation[view]))
            frame.on_view('reference', stamp, (r.reference_position_m[view], None if r.reference_orientation is None
                                               else r.reference_orientation[view]))
            frame.on_view('true_pose', stamp, (r.true_position_m[view], None if r.true_orientation is None
                                               else r.true_orientation[view]))
            frame.on_view('true_tension', stamp, r.true_tension_n[view])
            drawn = frame.take()
            if drawn is not None:
                write(contract.MARKERS, stamp, marker_array(drawn[1], header(stamp)), order)


def marker_array(shapes: list[Shape], header):
    """A frame of the markers node (cdpr_fdi.nodes.markers_node.marker_array) in the bag's types:
    DELETEALL, then every shape, its points in the world frame."""
    types = TYPESTORE.types
    marker, point = types['visualization_msgs/msg/Marker'], types['geometry_msgs/msg/Point']
    colour = types['std_msgs/msg/ColorRGBA']
    header = types['std_msgs/msg/Header'](stamp=header.stamp, frame_id=FRAME_ID)
    no_bytes = np.zeros(0, dtype=np.uint8)

    def make(action, shape: Shape | None = None):
        scale = 0.0 if shape is None else float(shape.scale_m)
        colours = [] if shape is None else [colour(*rgba) for rgba in shape.point_colours]
        first = colour(0.0, 0.0, 0.0, 0.0) if shape is None else colour(*shape.colours[0].tolist())
        return marker(
            header=header, ns='' if shape is None else shape.namespace,
            id=0 if shape is None else shape.id,
            type=0 if shape is None else getattr(marker, shape.kind), action=action,
            pose=types['geometry_msgs/msg/Pose'](
                position=point(0.0, 0.0, 0.0),
                orientation=types['geometry_msgs/msg/Quaternion'](0.0, 0.0, 0.0, 1.0)),
            scale=types['geometry_msgs/msg/Vector3'](scale, scale, scale),
            color=first,
            lifetime=types['builtin_interfaces/msg/Duration'](sec=0, nanosec=0),
            frame_locked=False,
            points=[] if shape is None else [point(*map(float, xyz)) for xyz in shape.points_m],
            colors=colours, texture_resource='',
            texture=types['sensor_msgs/msg/CompressedImage'](header=header, format='', data=no_bytes),
            uv_coordinates=[], text='', mesh_resource='',
            mesh_file=types['visualization_msgs/msg/MeshFile'](filename='', data=no_bytes),
            mesh_use_embedded_materials=False)

    return types['visualization_msgs/msg/MarkerArray'](
        markers=[make(marker.DELETEALL)] + [make(marker.ADD, shape) for shape in shapes])


def plant_diagnostics(recording: Recording, header, namespace: str):
    """What the plant simulator's last status says of the run, as its node reports it on
    /diagnostics: the instants it parted cables, its states, the figures from every tick."""
    types = TYPESTORE.types
    status = types['diagnostic_msgs/msg/DiagnosticStatus']
    values = {contract.BROKEN_AT_KEY: json.dumps({str(cable + 1): at for cable, at
                                                 in (recording.broken_at_s or {}).items()}),
              STATES_TOTAL_KEY: str(recording.time_s.size),
              contract.RUN_FIGURES_KEY: json.dumps(recording.figures)}
    return types['diagnostic_msgs/msg/DiagnosticArray'](header=header, status=[status(
        level=status.OK, name=f'{namespace}/{contract.PLANT_SIMULATOR}', message='', hardware_id='cdpr',
        values=[types['diagnostic_msgs/msg/KeyValue'](key=key, value=value) for key, value in values.items()])])


def supervisor_diagnostics(summary: dict, header, namespace: str):
    """The supervisor's summary as its node reports it on /diagnostics (`fdi KEY`: JSON)."""
    types = TYPESTORE.types
    status = types['diagnostic_msgs/msg/DiagnosticStatus']
    return types['diagnostic_msgs/msg/DiagnosticArray'](header=header, status=[status(
        level=status.ERROR if summary.get('fault') else status.OK,
        name=f'{namespace}/supervisor', message=summary.get('fault') or '', hardware_id='cdpr',
        values=[types['diagnostic_msgs/msg/KeyValue'](key=f'fdi {key}', value=json.dumps(value))
                for key, value in summary.items()])])
