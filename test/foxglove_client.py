"""
A Foxglove WebSocket client for the tests, written from the published protocol.

Foxglove's ws-protocol (subprotocol ``foxglove.websocket.v1``; the Foxglove
SDK's server of 0.30 names it ``foxglove.sdk.v1``, both are offered): JSON
text frames with an ``op`` (serverInfo, advertise, subscribe, unsubscribe,
client advertise, getParameters, setParameters, parameterValues, status),
binary frames with a one-byte opcode: server messageData 0x01 (u32
subscription id, u64 timestamp [ns], payload, little endian), client
clientPublish 0x01 (u32 client channel id, payload). websocket-client speaks
WebSocket; nothing of leadscrew_sim is used here.
"""
import json
import socket
import struct
import time

import websocket

SUBPROTOCOLS = ['foxglove.sdk.v1', 'foxglove.websocket.v1']


def free_port():
    """Return a TCP port that is free on 127.0.0.1 now."""
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


class FoxgloveClient:
    """One connection: the server's info and channels, subscriptions, publishing, parameters."""

    def __init__(self, port, timeout=60.0, proc=None, rcvbuf=None):
        """
        Connect, retrying until the server listens; read serverInfo.

        Gives up after ``timeout`` [s] or when ``proc`` (a NodeProcess or a
        Popen of the server) has ended.

        ``rcvbuf``: the socket's receive buffer [bytes] (small: a client that
        stops reading stalls the server's sends sooner).
        """
        end = time.monotonic() + timeout
        opts = () if rcvbuf is None else ((socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf),)
        while True:
            try:
                self.ws = websocket.create_connection(
                    f'ws://127.0.0.1:{port}', subprotocols=SUBPROTOCOLS, timeout=5.0,
                    sockopt=opts)
                break
            except (OSError, websocket.WebSocketException):
                popen = getattr(proc, 'proc', proc)     # a NodeProcess or a Popen
                if time.monotonic() > end or (popen is not None and popen.poll() is not None):
                    raise
                time.sleep(0.2)
        self.channels = {}        # topic -> advertised channel dict
        self.statuses = []        # status messages
        self.parameter_values = []   # parameterValues messages
        self.data = {}            # subscription id -> [(timestamp ns, payload)]
        self.server_info = None
        self._next_sub = 1
        self._next_chan = 1
        while self.server_info is None:
            self.poll(1.0)

    def close(self):
        """Close the connection."""
        self.ws.close()

    def poll(self, timeout):
        """Read one frame (waiting up to ``timeout`` [s]); return False if none came."""
        self.ws.settimeout(timeout)
        try:
            opcode, frame = self.ws.recv_data()
        except websocket.WebSocketTimeoutException:
            return False
        if opcode == websocket.ABNF.OPCODE_TEXT:
            msg = json.loads(frame.decode())
            op = msg['op']
            if op == 'serverInfo':
                self.server_info = msg
            elif op == 'advertise':
                for ch in msg['channels']:
                    self.channels[ch['topic']] = ch
            elif op == 'status':
                self.statuses.append(msg)
            elif op == 'parameterValues':
                self.parameter_values.append(msg)
        elif opcode == websocket.ABNF.OPCODE_BINARY and frame[:1] == b'\x01':
            sub, stamp = struct.unpack_from('<IQ', frame, 1)
            self.data.setdefault(sub, []).append((stamp, bytes(frame[13:])))
        return True

    def poll_until(self, pred, timeout):
        """Read frames until ``pred()`` holds or ``timeout`` [s]; return pred()."""
        end = time.monotonic() + timeout
        while not pred() and time.monotonic() < end:
            self.poll(0.2)
        return pred()

    def wait_channels(self, topics, timeout=20.0):
        """Wait until every topic is advertised."""
        return self.poll_until(lambda: all(t in self.channels for t in topics), timeout)

    def subscribe(self, topic):
        """Subscribe to an advertised topic; return the subscription id."""
        sub = self._next_sub
        self._next_sub += 1
        self.data[sub] = []
        self.ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
            {'id': sub, 'channelId': self.channels[topic]['id']}]}))
        return sub

    def unsubscribe(self, sub):
        """End a subscription."""
        self.ws.send(json.dumps({'op': 'unsubscribe', 'subscriptionIds': [sub]}))

    def advertise(self, topic, schema_name, encoding='cdr'):
        """Advertise a client channel; return its id."""
        cid = self._next_chan
        self._next_chan += 1
        self.ws.send(json.dumps({'op': 'advertise', 'channels': [
            {'id': cid, 'topic': topic, 'encoding': encoding, 'schemaName': schema_name}]}))
        return cid

    def publish(self, channel_id, payload):
        """Send one clientPublish message."""
        self.ws.send_binary(b'\x01' + struct.pack('<I', channel_id) + payload)

    def get_parameters(self, names, request_id, timeout=10.0):
        """Return {name: value} of a getParameters answer."""
        self.ws.send(json.dumps({'op': 'getParameters', 'parameterNames': names,
                                 'id': request_id}))
        return self._answer(request_id, timeout)

    def set_parameters(self, values, request_id, timeout=10.0):
        """Send setParameters {name: value}; return {name: value} of the answer."""
        self.ws.send(json.dumps({'op': 'setParameters', 'id': request_id, 'parameters': [
            {'name': k, 'value': v} for k, v in values.items()]}))
        return self._answer(request_id, timeout)

    def subscribe_parameters(self, names):
        """Ask for parameterValues whenever one of ``names`` changes."""
        self.ws.send(json.dumps({'op': 'subscribeParameterUpdates', 'parameterNames': names}))

    def _answer(self, request_id, timeout):
        def found():
            return next((m for m in self.parameter_values if m.get('id') == request_id), None)
        assert self.poll_until(lambda: found() is not None, timeout), request_id
        return {p['name']: p.get('value') for p in found()['parameters']}
