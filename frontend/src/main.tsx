/** Entry point: take the API token from the URL, start the shared socket, render the shell. */
import { StrictMode } from 'react';
import { createRoot } from 'react-dom/client';
import 'uplot/dist/uPlot.min.css';
import './styles.css';
import { captureTokenFromUrl } from './api/auth';
import { App } from './App';
import { startControlStore } from './state/control';
import { startStore } from './state/store';

captureTokenFromUrl();
startStore();
startControlStore();

const root = document.getElementById('root');
if (!root) throw new Error('index.html has no #root element');
createRoot(root).render(
  <StrictMode>
    <App />
  </StrictMode>,
);
