#!/usr/bin/env python3
"""Drives headless Chromium over its DevTools pipe (--remote-debugging-pipe; standard library only)
for the live view's browser tests: opens a page and runs actions on it in order.

  headless_page.py URL [--size 1280,800] [--timeout 30] ACTION...

Actions (each a separate argument):
  wait:S             sleep S seconds of real time
  until:JS           wait (at most --timeout s) until the JavaScript expression is true on every
                     open page; `s` is the page's window.fogmapState there
  state:FILE         write the first page's #fogmap-state text (JSON) to FILE
  states:FILE        write a JSON list of every open page's state to FILE
  shot:FILE          a PNG screenshot of the first page
  run:COMMAND        run a shell command (e.g. kill the root), failing when it fails
  eval:JS            evaluate JavaScript on the first page (e.g. to remember a count for an until)
  open:N             open URL in N more browsers (each its own Chromium: a browser opens at most
                     6 connections to one server, and each page's event stream holds one)
  click:X,Y          a left click on the first page

A page that loads with a live event stream never finishes loading, so Chromium's one-shot flags
(--dump-dom, --screenshot) capture it before its first event or hang; this driver reads the page
whenever the test asks. Exits 0 when every action succeeded, 1 with the reason otherwise, 77 when
Chromium cannot be started.
"""
import base64
import json
import os
import select
import shutil
import subprocess
import sys
import time

SKIP = 77


class Browser:
    """One headless Chromium; commands on fd 3, replies on fd 4, NUL-terminated JSON."""

    def __init__(self, size):
        self.size = size
        cmd_r, self.cmd_w = os.pipe()
        self.res_r, res_w = os.pipe()
        args = ['chromium', '--headless', '--no-sandbox', '--disable-gpu', '--remote-debugging-pipe',
                f'--window-size={size[0]},{size[1]}', '--hide-scrollbars', '--mute-audio', '--no-first-run',
                'about:blank']

        def child_fds():
            os.dup2(cmd_r, 3)
            os.dup2(res_w, 4)

        self.proc = subprocess.Popen(args, pass_fds=(3, 4), preexec_fn=child_fds,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(cmd_r)
        os.close(res_w)
        self.buffer = b''
        self.next_id = 0
        self.sessions = []
        self.errors = []  # uncaught exceptions of the pages

    def send(self, method, params=None, session=None, timeout=15.0):
        self.next_id += 1
        message = {'id': self.next_id, 'method': method, 'params': params or {}}
        if session:
            message['sessionId'] = session
        os.write(self.cmd_w, json.dumps(message).encode() + b'\0')
        deadline = time.monotonic() + timeout
        while True:
            try:
                replies = self._read(deadline)
            except TimeoutError:
                raise TimeoutError(f'no answer from the browser to {method} within {timeout:g} s') from None
            for reply in replies:
                if reply.get('id') == self.next_id:
                    if 'error' in reply:
                        raise RuntimeError(f'{method}: {reply["error"]}')
                    return reply.get('result', {})

    def _read(self, deadline):
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError('no answer from the browser')
        ready, _, _ = select.select([self.res_r], [], [], left)
        if ready:
            chunk = os.read(self.res_r, 1 << 20)
            if not chunk:
                raise RuntimeError('the browser closed its pipe')
            self.buffer += chunk
        out = []
        while b'\0' in self.buffer:
            raw, self.buffer = self.buffer.split(b'\0', 1)
            message = json.loads(raw)
            if message.get('method') == 'Runtime.exceptionThrown':
                self.errors.append(json.dumps(message['params'])[:300])
            out.append(message)
        return out

    def open(self, url):
        target = self.send('Target.createTarget', {'url': 'about:blank'})['targetId']
        session = self.send('Target.attachToTarget', {'targetId': target, 'flatten': True})['sessionId']
        self.send('Emulation.setDeviceMetricsOverride',
                  {'width': self.size[0], 'height': self.size[1], 'deviceScaleFactor': 1, 'mobile': False}, session)
        self.send('Page.enable', session=session)
        self.send('Runtime.enable', session=session)
        self.send('Page.navigate', {'url': url}, session)
        self.sessions.append(session)

    def eval(self, expression, session):
        result = self.send('Runtime.evaluate', {'expression': expression, 'returnByValue': True}, session)
        if 'exceptionDetails' in result:
            raise RuntimeError(json.dumps(result['exceptionDetails'])[:300])
        return result['result'].get('value')

    def state(self, session):
        return self.eval("(() => { const e = document.getElementById('fogmap-state');"
                         " return e ? e.textContent : 'null'; })()", session)

    def close(self):
        try:
            self.send('Browser.close', timeout=5)
        except Exception:
            pass
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def main(argv):
    if len(argv) < 2 or argv[1] in ('-h', '--help'):
        print(__doc__)
        return 0 if len(argv) >= 2 else 2
    url = argv[1]
    size = (1280, 800)
    timeout = 30.0
    actions = []
    rest = argv[2:]
    while rest:
        if rest[0] == '--size':
            size = tuple(int(v) for v in rest[1].split(','))
            rest = rest[2:]
        elif rest[0] == '--timeout':
            timeout = float(rest[1])
            rest = rest[2:]
        else:
            actions.append(rest[0])
            rest = rest[1:]
    if shutil.which('chromium') is None:
        print('headless_page: chromium is not installed (tools/install-deps.sh installs it)', file=sys.stderr)
        return SKIP
    browsers = []
    try:
        browsers.append(Browser(size))
        browsers[0].send('Browser.getVersion', timeout=30)
    except Exception as e:  # the browser does not start here (no display stack, no memory, ...)
        print(f'headless_page: chromium does not start: {e}', file=sys.stderr)
        for b in browsers:
            b.close()
        return SKIP
    browser = browsers[0]
    pages = []  # (browser, session) of every open page, the first page first

    def open_page(b):
        b.open(url)
        pages.append((b, b.sessions[-1]))

    status = 0
    try:
        open_page(browser)
        for action in actions:
            kind, _, arg = action.partition(':')
            if kind == 'wait':
                time.sleep(float(arg))
            elif kind == 'until':
                deadline = time.monotonic() + timeout
                check = f'(() => {{ const s = window.fogmapState; return !!(s && ({arg})); }})()'
                while not all(b.eval(check, session) for b, session in pages):
                    if time.monotonic() > deadline:
                        raise RuntimeError(f'not within {timeout:g} s: {arg}; the page says {browser.state(browser.sessions[0])}')
                    time.sleep(0.2)
            elif kind == 'state':
                with open(arg, 'w') as f:
                    f.write(browser.state(browser.sessions[0]))
            elif kind == 'states':
                with open(arg, 'w') as f:
                    f.write('[' + ','.join(b.state(session) for b, session in pages) + ']')
            elif kind == 'shot':
                data = browser.send('Page.captureScreenshot', {'format': 'png'}, browser.sessions[0])['data']
                with open(arg, 'wb') as f:
                    f.write(base64.b64decode(data))
            elif kind == 'run':
                done = subprocess.run(arg, shell=True, timeout=timeout)
                if done.returncode != 0:
                    raise RuntimeError(f'{arg}: exit code {done.returncode}')
            elif kind == 'eval':
                browser.eval(arg, browser.sessions[0])
            elif kind == 'open':
                for _ in range(int(arg)):
                    browsers.append(Browser(size))
                    open_page(browsers[-1])
            elif kind == 'click':
                x, y = (float(v) for v in arg.split(','))
                for event in ('mousePressed', 'mouseReleased'):
                    browser.send('Input.dispatchMouseEvent',
                                 {'type': event, 'x': x, 'y': y, 'button': 'left', 'clickCount': 1}, browser.sessions[0])
            else:
                raise RuntimeError(f'unknown action {action!r}')
            print(f'headless_page: {action[:80]} done', file=sys.stderr)
    except Exception as e:
        print(f'headless_page: {e}', file=sys.stderr)
        status = 1
    finally:
        for b in browsers:
            for error in b.errors:
                print(f'headless_page: the page threw: {error}', file=sys.stderr)
                status = 1
            b.close()
    return status


if __name__ == '__main__':
    sys.exit(main(sys.argv))
